"""The thermal safety monitor: its bound by hand, its overrides (torque limit, faster release, stop), and that with
it in the loop no command leaves the controller whose bound passes T_safe, in any state."""

from __future__ import annotations

import math
import random
from dataclasses import replace

import pytest

from ecu_stub.calibration import FrictionMap
from ecu_stub.controller import CreepController
from ecu_stub.monitor import ThermalMonitor, release_time_s, worst_heat_w, worst_slip_rpm

from .test_controller import CREEP, DT, FLAT, Clock, creeping, run

S = FLAT.strategy
RPM = 2 * math.pi / 60


def hand_bound(T, P_mpa, slip_rpm, C=FLAT.CL.C_plate_j_k):
    """B = T + e + mu k P slip * tau / C with the flat map's mu = 0.07."""
    Q = 0.07 * FLAT.CL.k_geom_m3 * P_mpa * 1e6 * slip_rpm * RPM
    return T + S.prediction_error_k + Q * (0.5 * S.stop_release_s + S.hydraulic_lag_s + DT) / C


def test_bound_by_hand_with_the_worst_slip_and_pressure():
    m = ThermalMonitor(FLAT)
    assert release_time_s(FLAT, DT) == pytest.approx(0.5 * S.stop_release_s + S.hydraulic_lag_s + DT)
    assert worst_slip_rpm(-40.0, 150.0) == 150.0 and worst_slip_rpm(-200.0, 150.0) == 200.0
    assert worst_heat_w(FLAT, "CL", 200.0, 100.0, 150.0, 0.5) == pytest.approx(
        0.07 * FLAT.CL.k_geom_m3 * 0.5e6 * 150.0 * RPM, rel=1e-9)
    assert m.bound_c("CL", 240.0, 100.0, 150.0, 0.5, DT) == pytest.approx(hand_bound(240.0, 0.5, 150.0), rel=1e-12)
    # the measured pressure counts when it is the larger (the piston lags a falling command)
    v = m.check({"CL": 240.0, "CH": 100.0}, {"CL": 100.0, "CH": 120.0}, 150.0, {"CL": 0.2, "CH": 0.0},
                {"CL": 0.5, "CH": 0.0}, "CL", DT)
    assert v.bound_c["CL"] == pytest.approx(hand_bound(240.0, 0.5, 150.0), rel=1e-12)


def test_no_override_under_t_safe():
    m = ThermalMonitor(FLAT)
    v = m.check({"CL": 200.0, "CH": 100.0}, {"CL": 100.0, "CH": 120.0}, 150.0, {"CL": 0.6, "CH": 0.0},
                {"CL": 0.6, "CH": 0.0}, "CL", DT)
    assert v.P_limit_mpa == {} and not v.stop and max(v.bound_c.values()) < S.T_safe_c


def test_limits_the_pressure_to_the_bound_and_stops_only_for_the_carrying_clutch():
    m = ThermalMonitor(FLAT)
    T = S.T_safe_c - S.prediction_error_k - 1.0  # 1 K of room: far less than a 0.8-MPa command's heat to come
    assert hand_bound(T, 0.8, 150.0) > S.T_safe_c
    args = ({"CL": T, "CH": 100.0}, {"CL": 100.0, "CH": 120.0}, 150.0, {"CL": 0.8, "CH": 0.3},
            {"CL": 0.0, "CH": 0.3})
    off_going = m.check(*args, "CH", DT)  # CL is handing over to CH: a faster release, no stop
    P = off_going.P_limit_mpa["CL"]
    assert 0.0 < P < 0.8 and not off_going.stop and "CH" not in off_going.P_limit_mpa
    assert hand_bound(T, P, 150.0) == pytest.approx(S.T_safe_c, abs=1e-6) and off_going.bound_c["CL"] <= S.T_safe_c
    carrying = m.check(*args, "CL", DT)  # CL carries the vehicle: limited, and the vehicle is stopped
    assert carrying.P_limit_mpa["CL"] == P and carrying.stop
    # a measured pressure that alone passes the bound: the command goes to zero at once
    hot = m.check({"CL": T, "CH": 100.0}, {"CL": 100.0, "CH": 120.0}, 150.0, {"CL": 0.8, "CH": 0.3},
                  {"CL": 0.8, "CH": 0.3}, "CH", DT)
    assert hot.P_limit_mpa["CL"] == 0.0 and not hot.stop


def test_controller_stops_when_the_monitor_limits_the_clutch_that_carries_the_vehicle():
    ctrl, clock = creeping()
    inp = replace(CREEP, P_CL_mpa=0.6, v_mps=0.2)
    run(ctrl, clock, inp, 0.5)
    # a strategy that would plan around the margin: the monitor judges with a T_safe 30 K lower than the strategy's
    # (the controller's methods are read-only in the compiled build: the monitor's calibration is the seam). CL under
    # the strategy's handover limit, but for the monitor a full command's heat to come passes T_safe, and CH cannot
    # take over (hot for the monitor)
    T_safe = S.T_safe_c - 30.0
    ctrl.monitor = ThermalMonitor(replace(FLAT, strategy=replace(S, T_safe_c=T_safe)))
    T = T_safe - ctrl.margin_k("CL") - 0.5  # (the strategy's margin, which it hands the monitor)
    ctrl.T_pred = {"CL": T, "CH": T_safe - 5.0}
    ctrl.near_limit_since = None
    assert T < ctrl.limit("CL")  # the strategy alone keeps creeping on CL
    out = ctrl.update(replace(inp, P_CL_mpa=0.0, T_oil_CL_c=T, T_oil_CH_c=T_safe - 5.0), clock.tick())
    assert out.state == "STOPPED_OVERHEAT" and out.brake_request
    assert ctrl.bound["CL"] == pytest.approx(T_safe, abs=1e-6) and out.P_CL_cmd_mpa > 0.0  # ramps out from there


def test_controller_releases_the_off_going_clutch_faster_when_its_bound_would_pass_t_safe():
    ctrl, clock = creeping()
    inp = replace(CREEP, P_CL_mpa=0.6, v_mps=0.2)
    run(ctrl, clock, inp, 0.5)
    still = replace(inp, clutch_in_rpm=0.0, cl_out_rpm=0.0, ch_out_rpm=0.0)
    ctrl.T_pred = {"CL": ctrl.limit("CL", 0.0) + 0.05, "CH": 150.0}
    out = ctrl.update(replace(still, T_oil_CL_c=ctrl.T_pred["CL"], T_oil_CH_c=150.0), clock.tick())
    assert out.state == "HANDOVER" and out.active_clutch == "CH"
    # a brake drags the vehicle down during the crossover: the strategy asks CL for more, the monitor refuses
    T = S.T_safe_c - ctrl.margin_k("CL") - 0.3  # (the strategy's margin, which it hands the monitor)
    ctrl.T_pred["CL"] = T
    out = ctrl.update(replace(inp, v_mps=0.05, P_CL_mpa=0.0, T_oil_CL_c=T), clock.tick())
    assert out.state == "HANDOVER" and not out.brake_request
    assert 0.0 <= out.P_CL_cmd_mpa < ctrl.pressure_for("CL", 0.9 * ctrl.F_cmd, inp)
    assert ctrl.bound["CL"] <= S.T_safe_c + 1e-6


def test_the_on_coming_clutch_takes_the_force_the_monitor_takes_off_the_off_going_one():
    """As above, on a map whose mu falls with pressure (0.10 at 0, 0.06 at 1.5 MPa): the on-coming CH is commanded
    the pressure for the wheel force less what CL gives at its limited pressure, mu looked up there
    (:meth:`force_at`), not CL's capacity scaled by P / P_max (mu at 1.5 MPa: CL's force too low, CH's too high)."""
    by_p = replace(FLAT, friction=FrictionMap((20.0, 320.0), (0.0, 400.0), (0.0, 1.5),
                                              tuple(((0.10, 0.06), (0.10, 0.06)) for _ in range(2))))
    ctrl, clock = creeping(by_p)
    inp = replace(CREEP, P_CL_mpa=0.6, v_mps=0.2)
    run(ctrl, clock, inp, 0.5)
    still = replace(inp, clutch_in_rpm=0.0, cl_out_rpm=0.0, ch_out_rpm=0.0)
    ctrl.T_pred = {"CL": ctrl.limit("CL", 0.0) + 0.05, "CH": 150.0}
    out = ctrl.update(replace(still, T_oil_CL_c=ctrl.T_pred["CL"], T_oil_CH_c=150.0), clock.tick())
    assert out.state == "HANDOVER"
    T = S.T_safe_c - ctrl.margin_k("CL") - 0.3  # (the strategy's margin, which it hands the monitor)
    ctrl.T_pred["CL"] = T
    hot = replace(inp, v_mps=0.05, P_CL_mpa=0.0, T_oil_CL_c=T)
    out = ctrl.update(hot, clock.tick())
    assert out.state == "HANDOVER" and 0.0 < out.P_CL_cmd_mpa < 0.6  # limited, not released
    rest = ctrl.F_cmd - ctrl.force_at("CL", out.P_CL_cmd_mpa, hot)
    assert out.P_CH_cmd_mpa == pytest.approx(ctrl.pressure_for("CH", rest, hot), rel=1e-6)
    old = ctrl.F_cmd - out.P_CL_cmd_mpa * ctrl.force_capacity("CL", hot) / by_p.speed.P_max_mpa
    assert out.P_CH_cmd_mpa < 0.97 * ctrl.pressure_for("CH", old, hot)


@pytest.mark.parametrize("seed", range(3))
def test_no_command_leaves_the_controller_with_its_bound_above_t_safe(seed):
    """Random inputs around a hot creep, through every state the inputs reach: after each cycle, every clutch's
    bound at the commands sent (and the measured pressures) is at most T_safe."""
    rng = random.Random(seed)
    ctrl, clock = CreepController(FLAT), Clock()
    monitor = ThermalMonitor(FLAT)
    states = set()
    for k in range(3000):
        T_oil = (150.0, 240.0) if k < 2000 else (240.0, 249.0)  # at the end both too hot to take over: stops
        inp = replace(CREEP, clutch_in_rpm=rng.uniform(50.0, 300.0), cl_out_rpm=rng.uniform(-20.0, 60.0),
                      ch_out_rpm=rng.uniform(-20.0, 40.0), v_mps=rng.uniform(-0.05, 0.3),
                      P_CL_mpa=rng.uniform(0.0, 1.2), P_CH_mpa=rng.uniform(0.0, 1.2),
                      T_oil_CL_c=rng.uniform(*T_oil), T_oil_CH_c=rng.uniform(*T_oil),
                      creep_request=rng.random() > 0.005, brake_pct=rng.choice((0.0, 0.0, 0.0, 4.5, 50.0)),
                      plant_valid=rng.random() > 0.01)
        out = ctrl.update(inp, clock.tick())
        states.add(out.state)
        if not inp.plant_valid:
            continue
        P_cmd, P_meas = {"CL": out.P_CL_cmd_mpa, "CH": out.P_CH_cmd_mpa}, {"CL": inp.P_CL_mpa, "CH": inp.P_CH_mpa}
        for c in ("CL", "CH"):
            T_safe_ok = monitor.bound_c(c, ctrl.T_pred[c], inp.slip_rpm(c), inp.clutch_in_rpm,
                                        max(P_cmd[c], P_meas[c]), DT) <= S.T_safe_c + 1e-6
            opened = P_cmd[c] == 0.0  # limited to zero: the release starts now, whatever the lagging piston does
            assert T_safe_ok or opened, (k, c, out)
    assert {"ENGAGE", "CREEP", "HANDOVER", "STOPPED_OVERHEAT", "FAULT"} <= states
