"""The TCU's clutch model (``ecu_stub.clutch_model``) by hand: the pressure for a torque with mu looked up at that
pressure, and the friction heat with mu at the predictor's low-passed slip."""

from __future__ import annotations

import math
import random

import pytest

from ecu_stub.calibration import FrictionMap, load_calibration
from ecu_stub.clutch_model import friction_heat, heat_w, mu_lookup, pressure_for_torque

CAL = load_calibration()
CL = CAL.CL
K = CL.k_geom_m3 * 1e6  # N m per MPa per unit mu


def by_pressure(*mu: float) -> FrictionMap:
    """A map whose mu depends on pressure only: ``mu`` at 0, 0.5, 1.0 and 1.5 MPa, any temperature and slip."""
    return FrictionMap((20.0, 320.0), (0.0, 400.0), (0.0, 0.5, 1.0, 1.5), (((*mu,), (*mu,)),) * 2)


def torque(m: FrictionMap, P: float) -> float:
    return mu_lookup(m)(150.0, 100.0, P) * K * P


def test_the_pressure_for_a_torque_solves_m_equal_mu_of_p_k_p_in_closed_form():
    """mu 0.10 - 0.04 P between 0.5 and 1.0 MPa: M = K P (0.10 - 0.04 P); at P = 0.75, mu P = 0.0525, so the torque
    0.0525 K gives back 0.75 MPa from any starting pressure (M rises with P on this map: one crossing)."""
    m = by_pressure(0.10, 0.08, 0.06, 0.06)
    M = 0.0525 * K
    assert torque(m, 0.75) == pytest.approx(M, rel=1e-12)
    for start in (0.0, 0.3, 0.75, 1.2, 1.5):
        assert pressure_for_torque(m, CL, 150.0, 100.0, M, start) == pytest.approx(0.75, rel=1e-12)
    # by hand in the first span (mu 0.10 - 0.04 P too): mu P = 0.02 -> P = (0.10 - sqrt(0.01 - 0.0032)) / 0.08
    assert pressure_for_torque(m, CL, 150.0, 100.0, 0.02 * K, 1.0) == pytest.approx(
        (0.10 - math.sqrt(0.01 - 0.16 * 0.02)) / 0.08, rel=1e-12)


def test_no_torque_needs_no_pressure_and_more_than_the_map_gives_the_top_of_its_axis():
    m = by_pressure(0.10, 0.08, 0.06, 0.06)
    assert pressure_for_torque(m, CL, 150.0, 100.0, 0.0, 0.7) == 0.0
    assert pressure_for_torque(m, CL, 150.0, 100.0, -5.0, 0.7) == 0.0
    assert pressure_for_torque(m, CL, 150.0, 100.0, 0.2 * K, 0.0) == 1.5  # mu P at most 0.09


def test_where_the_torque_is_not_monotone_in_pressure_the_crossing_next_to_the_last_command_is_taken():
    """mu 0.20 at 0.5 MPa, 0.08 at 1.0: mu P is 0.10 at 0.5 MPa, 0.08 at 1.0 and 0.12 at 1.5, so 0.09 is reached
    in three spans. From a command in the first span the answer stays in it, from one in the last, in the last:
    the command moves continuously, and each answer gives the torque."""
    m = by_pressure(0.10, 0.20, 0.08, 0.08)
    M = 0.09 * K
    low, high = pressure_for_torque(m, CL, 150.0, 100.0, M, 0.2), pressure_for_torque(m, CL, 150.0, 100.0, M, 1.4)
    assert 0.0 < low < 0.5 and 1.0 < high < 1.5
    assert torque(m, low) == pytest.approx(M, rel=1e-12) and torque(m, high) == pytest.approx(M, rel=1e-12)


def test_the_shipped_map_inverts_exactly():
    """On the identified map, anywhere in its range and from any last command: the torque at the pressure found is
    the torque asked for."""
    rng = random.Random(7)
    m, mu_of = CAL.friction, mu_lookup(CAL.friction)
    for _ in range(2000):
        T, slip, P, start = rng.uniform(40, 260), rng.uniform(0, 300), rng.uniform(0.01, 1.5), rng.uniform(0, 1.5)
        M = mu_of(T, slip, P) * K * P
        Q = pressure_for_torque(m, CL, T, slip, M, start)
        assert mu_of(T, slip, Q) * K * Q == pytest.approx(M, rel=1e-9)


def test_the_friction_heat_takes_mu_at_the_given_slip_and_the_power_at_the_measured_one():
    """(4) Q = mu M_per_mu P |slip|: with ``mu_slip_rpm`` mu is looked up there (the predictor's low-passed slip), the
    power still at the measured slip."""
    m = CAL.friction
    mu_at = mu_lookup(m)
    assert friction_heat(m, CL, 200.0, 180.0, 0.4, 120.0) == pytest.approx(heat_w(mu_at(200.0, 120.0, 0.4), CL, 0.4,
                                                                                  180.0), rel=1e-15)
    assert friction_heat(m, CL, 200.0, -180.0, 0.4) == friction_heat(m, CL, 200.0, 180.0, 0.4, -180.0)
    assert heat_w(0.05, CL, 0.4, 180.0) == pytest.approx(0.05 * K * 0.4 * 180.0 * 2 * math.pi / 60, rel=1e-12)
