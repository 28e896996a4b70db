"""Section III.C: the four 100-s rig cases against the published numbers (issue 2's bands).

Note: thermal.clutch.test.h_plate_oil is fitted (least squares, one parameter) to these four rises, so the rise checks
test that one structure fits all four at once, not an independent prediction. The torque and mu checks of case 4
are not fitted (formula (6) as read, N = 2 from the geometry)."""

from __future__ import annotations

import pytest

from dsg_hil.paper.reference import TOL_MU, TOL_RISE_C, TOL_TORQUE_REL
from dsg_hil.paper.validation import run_validation, validation_json


@pytest.fixture(scope="module")
def results(params):
    return run_validation(params)


def test_temperature_rises_within_4_degc(results):
    for r in results:
        assert abs(r.trace.temperature_rise - r.reference.temperature_rise_c) <= TOL_RISE_C, r.reference


def test_case4_mu_within_band(results):
    t, ref = results[3].trace, results[3].reference
    assert abs(t.mu[0] - ref.mu_start) <= TOL_MU
    assert abs(t.mu[-1] - ref.mu_end) <= TOL_MU
    assert t.mu[-1] > t.mu[0]  # mu grows with temperature at constant P and speed, as in Fig. 5


def test_case4_torque_start_within_band(results):
    t, ref = results[3].trace, results[3].reference
    assert abs(t.torque[0] / ref.torque_start_nm - 1) <= TOL_TORQUE_REL


@pytest.mark.xfail(strict=True, reason="known mismatch: formula (6) as printed gives mu 0.0561 at 114 degC, "
                   "not 0.060, so the end torque is 7.0 % below 164.8 N m (docs/explanation/fitted.md, 'Validation')")
def test_case4_torque_end_within_band(results):
    t, ref = results[3].trace, results[3].reference
    assert abs(t.torque[-1] / ref.torque_end_nm - 1) <= TOL_TORQUE_REL


def test_torque_rises_with_temperature_in_case4(results):
    t = results[3].trace
    assert 1.04 < t.torque[-1] / t.torque[0] < 1.12  # paper: +10.2 %


def test_energy_balance_of_each_case(results):
    for r in results:
        t = r.trace
        assert t.friction_work + t.hydraulic_heat == pytest.approx(t.heat_stored + t.heat_to_environment, rel=1e-3)


def test_json_shape(results):
    data = validation_json(results)
    assert [c["case"] for c in data["cases"]] == [1, 2, 3, 4]
    for c in data["cases"]:
        assert set(c) >= {"pressure_mpa", "speed_rpm", "temperature_rise_c", "torque_start_nm", "torque_end_nm",
                          "mu_start", "mu_end"}


def test_rig_configuration_puts_the_test_clutch_in_slot_cl(params):
    """The rig is its own configuration: the test clutch and its lubrication as element CL, no flow through the
    idle slot CH, E at the start temperature; the vehicle's values are untouched."""
    from dsg_hil.physics.rig import rig_configuration
    rig = rig_configuration(params, 40.0)
    assert rig.clutch.CL == params.clutch.test and rig.thermal.clutch.CL == params.thermal.clutch.test
    assert rig.thermal.clutch.CH.Q_cool == 0.0 and rig.thermal.T_E == 40.0
    assert params.clutch.CL.N == 6 and params.thermal.clutch.CL.Q_cool != params.thermal.clutch.test.Q_cool
