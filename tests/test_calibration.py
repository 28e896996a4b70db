"""The parameter file's calibrated values are what their calibrations give today (not stale)."""

from __future__ import annotations

import pytest

from dsg_hil.calibration import calibrate_h_plate_oil, calibrate_stribeck


def test_stribeck_amplitude_matches_its_fit(params):
    fit = calibrate_stribeck(params)
    assert fit.mu_start == pytest.approx(0.063, abs=1e-6) and fit.mu_end == pytest.approx(0.075, abs=1e-6)
    assert params.friction.A_stribeck == pytest.approx(fit.A_stribeck, rel=2e-3)
    assert 80.0 < fit.slip_rpm < 150.0


@pytest.mark.slow
def test_plate_oil_heat_transfer_matches_its_fit(params):
    assert params.thermal.clutch.h_plate_oil == pytest.approx(calibrate_h_plate_oil(params), rel=5e-3)
