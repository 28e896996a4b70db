"""Reduced model of the Section V.B creep: quasi-static operating point by hand, the idealised strategy's
sequence, and the full plant under the same strategy against the reduced model."""

from __future__ import annotations

import math

import pytest

from dsg_hil.paper.calibration import friction_checks, reduced_creep, timeline_checks
from dsg_hil.paper.creep_model import creep_speed_for_slip, operating_point, pressure_for_torque, run_plant_creep
from dsg_hil.common.units import CV
from dsg_hil.physics.friction import friction_coefficient, torque_per_mu
from dsg_hil.sim.scenario import load_scenario


def test_operating_point_by_hand(params):
    """800 r/min engine, 0.2 m/s on 0.174 rad: speeds through the ratios, torques through the ratios and
    efficiencies of (10)-(12) at rest, heat = torque x slip."""
    pt, veh = params.powertrain, params.vehicle
    omega_e, v = 800.0 * CV.RPM_TO_RAD_S, 0.2
    op = operating_point(params, omega_e, v, 0.174)
    omega_1 = omega_e / 5.3585
    omega_4 = v / 0.1935 * 3.818 * 0.925
    wheel = (7840 * 9.81 * (0.123 * math.cos(0.174) + math.sin(0.174)) + 0.5 * 1.2 * 0.62 * 3.6 * v * v) * 0.1935
    for k, i_k, eta_k in (("CL", 1.59, pt.eta_L), ("CH", 0.92, pt.eta_H)):
        assert op.slip[k] == pytest.approx(omega_1 - omega_4 * i_k, rel=1e-12)
        M = wheel / (3.818 * pt.eta_b * 0.925 * pt.eta_1 * i_k * eta_k)
        assert op.torque[k] == pytest.approx(M, rel=1e-9)
        assert op.heat[k] == pytest.approx(M * op.slip[k], rel=1e-9)
    assert veh.m == 7840 and op.heat["CH"] > 2 * op.heat["CL"]  # CH always makes more heat (i_H < i_L)


def test_creep_speed_inverts_the_slip(params):
    omega_e = 800.0 * CV.RPM_TO_RAD_S
    for clutch in ("CL", "CH"):
        v = creep_speed_for_slip(params, omega_e, clutch, 10.0)
        assert operating_point(params, omega_e, v).slip[clutch] == pytest.approx(10.0, rel=1e-12)


def test_pressure_for_torque_solves_5_and_6(params):
    slip = 116.0 * CV.RPM_TO_RAD_S
    P, mu = pressure_for_torque(params, "CH", 1300.0, slip, 180.0)
    assert mu == pytest.approx(friction_coefficient(slip, 180.0, P, params.friction), rel=1e-6)
    assert mu * torque_per_mu(params.clutch.CH, P) == pytest.approx(1300.0, rel=1e-5)


def test_reduced_model_follows_the_papers_sequence(params):
    r = reduced_creep(params)
    assert [p.clutch for p in r.phases] == ["CL", "CH", "CL", "CH"] and r.stopped
    assert r.T_max["CL"] <= 250.0 + 1e-9 and r.T_max["CH"] <= 250.0 + 1e-9
    for a, b in zip(r.phases, r.phases[1:]):
        assert a.t_end == pytest.approx(b.t_start)
    assert sum(r.slip_time.values()) == pytest.approx(r.creep_time)


@pytest.mark.slow
def test_full_plant_under_the_idealised_strategy_matches_the_reduced_model(params):
    """The plant (torsional dynamics, stick/slip, pressure lag, (6) at the true slip) closed by a PI speed
    controller that hands over on the true plate temperature: the same timeline as the quasi-static model."""
    scenario = load_scenario()
    full, reduced = run_plant_creep(params, scenario), reduced_creep(params, scenario)
    assert [p.clutch for p in full.phases] == ["CL", "CH", "CL", "CH"] and full.stopped
    for f, r in zip(timeline_checks(full), timeline_checks(reduced)):
        assert f.simulated == pytest.approx(r.simulated, abs=2.0), f.name  # s or K
        assert f.ok, f
    for c in friction_checks(full):
        assert c.ok, c
