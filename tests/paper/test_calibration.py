"""The parameter file's calibrated values are what their calibrations give today (not stale), and with them the
reduced model meets Section V.B within issue 7's bands."""

from __future__ import annotations

import pytest

from dsg_hil.paper.calibration import (calibrate_h_plate_oil, calibrate_stribeck, calibrate_vehicle_thermal,
                                 friction_checks, reduced_creep, timeline_checks, vehicle_thermal)
from dsg_hil.paper.creep_model import creep_speed_for_slip
from dsg_hil.common.units import CV
from dsg_hil.sim.scenario import load_scenario


def test_stribeck_amplitude_matches_its_fit(params):
    fit = calibrate_stribeck(params)
    assert fit.mu_start == pytest.approx(0.063, abs=1e-6) and fit.mu_end == pytest.approx(0.075, abs=1e-6)
    assert params.friction.A_stribeck == pytest.approx(fit.A_stribeck, rel=2e-3)
    assert 80.0 < fit.slip_rpm < 140.0


def test_default_scenario_creeps_at_the_fitted_ch_slip(params):
    """The shipped scenario's creep speed is the one where CH slips the speed fitted with A_stribeck."""
    fit, s = calibrate_stribeck(params), load_scenario()
    v = max(d.desired_speed_mps for d in s.driver if d.creep_request)
    omega_e = s.engine_speed_rpm * CV.RPM_TO_RAD_S
    assert v == pytest.approx(creep_speed_for_slip(params, omega_e, "CH", fit.slip_rpm * CV.RPM_TO_RAD_S), abs=0.001)


def test_reduced_model_meets_section_vb(params):
    r = reduced_creep(params)
    for check in timeline_checks(r) + friction_checks(r):
        assert check.ok, check


@pytest.mark.slow
def test_vehicle_thermal_values_match_their_fit(params):
    fitted = calibrate_vehicle_thermal(params)
    for new, old in zip(fitted, vehicle_thermal(params)):
        assert old == pytest.approx(new, rel=1e-2)


@pytest.mark.slow
def test_plate_oil_heat_transfer_matches_its_fit(params):
    assert params.thermal.clutch.test.h_plate_oil == pytest.approx(calibrate_h_plate_oil(params), rel=5e-3)


def test_vehicle_clutches_share_the_rigs_heat_transfer_coefficient(params):
    """Tagged 'same friction lining and grooves as the test clutch': keep them equal when h is refitted."""
    t = params.thermal.clutch
    assert t.CL.h_plate_oil == t.CH.h_plate_oil == t.test.h_plate_oil
