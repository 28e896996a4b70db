"""Friction torque (5) and coefficient (6) against hand calculations and the paper's points. (6) takes SI (rad/s,
Pa); the paper states its points in r/min and MPa, converted here by hand (2 pi / 60, 1e6)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dsg_hil.physics.friction import (clutch_torque_capacity, friction_coefficient, friction_coefficient_at,
                                      friction_coefficient_grid, mean_friction_radius, pressure_factors,
                                      stribeck_term, torque_per_mu)
from dsg_hil.paper.reference import RIG_CASES

RPM = 2 * math.pi / 60  # rad/s per r/min
MPA = 1e6  # Pa per MPa


def four_printed_terms(n, T, P):
    """The last four terms of (6) as printed: n [r/min], T [degC], P [MPa], written out by hand."""
    return (0.01 * math.log(0.04398 * n + 1) / math.exp(0.005 * T)
            + 0.08 * (math.exp(-0.005 * T) - 1) * (math.exp(-0.0022 * n) - 1)
            - 0.005 * math.log(28.3 * P) + 0.035)


def printed_formula(n, T, P, A, P_floor_mpa):
    """All of (6) in the paper's units (the Stribeck reading of the first term, the pressure floor), by hand."""
    P = max(P, P_floor_mpa)
    D = (math.log(T) - 3.2) * (28.3 * P) ** 0.4 - 0.87 if T > 1.0 else 0.0
    first = A * math.exp(-((0.028574 * abs(n) / D) ** 5.16)) if D > 0.0 else 0.0
    return first + four_printed_terms(abs(n), T, P)


def test_mean_radius_and_torque_hand_calculation(params):
    r_m = 2 / 3 * (0.125**3 - 0.086**3) / (0.125**2 - 0.086**2)
    assert mean_friction_radius(0.086, 0.125) == pytest.approx(r_m)
    assert r_m == pytest.approx(0.10670, abs=1e-5)
    # Section III.C case 4 at the paper's mu: 0.054 * 2 * 0.3e6 Pa * 0.0427 m^2 * r_m = 147.6 N m (paper: 149.5)
    assert clutch_torque_capacity(0.054, params.clutch.test, 0.3e6) == pytest.approx(0.054 * 2 * 0.3e6 * 0.0427 * r_m)
    assert clutch_torque_capacity(0.054, params.clutch.test, 0.3e6) == pytest.approx(149.5, rel=0.02)


def test_zero_pressure_gives_zero_torque(params):
    assert torque_per_mu(params.clutch.CL, 0.0) == 0.0
    assert torque_per_mu(params.clutch.CL, -1e5) == 0.0
    assert math.isfinite(friction_coefficient(100.0 * RPM, 80.0, 0.0, params.friction))


@pytest.mark.parametrize("T, expected", [(40.0, 0.05303), (114.0, 0.05610)])
def test_section_iii_c_case4_points(params, T, expected):
    mu = friction_coefficient(300.0 * RPM, T, 0.3 * MPA, params.friction)
    assert mu == pytest.approx(four_printed_terms(300.0, T, 0.3), abs=1e-12)  # first term is zero there
    assert mu == pytest.approx(expected, abs=1e-5)


def test_si_friction_is_the_printed_formula_in_r_per_min_and_mpa(params):
    """Over the operating range, in both slip directions and below the pressure floor: mu(rad/s, Pa) is (6) as
    printed at the same point in r/min and MPa."""
    f = params.friction
    for n in (-350.0, -40.0, 0.0, 3.0, 25.0, 114.0, 300.0, 2000.0):
        for T in (0.5, 20.0, 40.0, 100.0, 180.0, 250.0):
            for P in (0.0, 0.03, 0.2, 0.75, 1.5):
                expected = printed_formula(n, T, P, f.A_stribeck, f.P_floor / MPA)
                assert friction_coefficient(n * RPM, T, P * MPA, f) == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_stribeck_term_is_zero_at_all_validation_points(params):
    for ref in RIG_CASES:
        for T in np.linspace(40.0, 40.0 + ref.temperature_rise_c + 5.0, 50):
            assert stribeck_term(ref.speed_rpm * RPM, T, ref.pressure_mpa * MPA, params.friction) < 1e-9


def test_section_v_mu_ch(params):
    """mu_CH 0.063 -> 0.075 at one slip speed (the calibration's 114 r/min), 100 -> 250 degC, 0.75 -> 0.65 MPa."""
    assert friction_coefficient(114.0 * RPM, 100.0, 0.75 * MPA, params.friction) == pytest.approx(0.063, abs=5e-4)
    assert friction_coefficient(114.0 * RPM, 250.0, 0.65 * MPA, params.friction) == pytest.approx(0.075, abs=5e-4)


def test_stribeck_first_term_by_hand(params):
    n, T, P = 114.0, 100.0, 0.75
    D = (math.log(T) - 3.2) * (28.3 * P) ** 0.4 - 0.87
    expected = params.friction.A_stribeck * math.exp(-((0.028574 * n / D) ** 5.16))
    assert stribeck_term(n * RPM, T, P * MPA, params.friction) == pytest.approx(expected)
    assert stribeck_term(-n * RPM, T, P * MPA, params.friction) == pytest.approx(expected)  # sign ignored
    assert stribeck_term(n * RPM, 20.0, P * MPA, params.friction) == 0.0  # D < 0 below ~25 degC
    assert stribeck_term(n * RPM, -5.0, P * MPA, params.friction) == 0.0


def test_whole_operating_range_is_finite_positive_plausible(params):
    n = np.linspace(0.0, 400.0, 81)[:, None, None]
    T = np.linspace(20.0, 300.0, 57)[None, :, None]
    P = np.linspace(0.0, 1.5, 31)[None, None, :]
    mu = friction_coefficient_grid(n * RPM, T, P * MPA, params.friction)
    assert mu.shape == (81, 57, 31)
    assert np.all(np.isfinite(mu))
    assert mu.min() > 0.01 and mu.max() < 0.15  # wet paper/steel: a few hundredths to about 0.15


def test_literal_prefactor_would_be_implausible(params):
    """Why A_stribeck is calibrated: the printed 23 gives mu >> 1 at creep slip speeds."""
    literal = replace(params.friction, A_stribeck=23.0)
    assert friction_coefficient(100.0 * RPM, 150.0, 0.7 * MPA, literal) > 1.0


def test_pressure_factors_by_hand_and_reused_as_computed(params):
    """The pressure's parts of (6), computed once for a pressure and passed to friction_coefficient_at, give mu
    bit for bit; the floor applies to them as to (6)."""
    f = params.friction
    factor, log_term = pressure_factors(0.5e6, f)
    assert factor == pytest.approx(14.15**0.4, rel=1e-15) and log_term == pytest.approx(0.005 * math.log(14.15))
    assert pressure_factors(0.0, f) == pressure_factors(f.P_floor, f)
    for w, T, P in ((0.0, 80.0, 0.3e6), (0.5, 150.0, 0.7e6), (31.4, 40.0, 0.0), (-2.1, 250.0, 1.5e6)):
        assert friction_coefficient_at(w, T, *pressure_factors(P, f), f) == friction_coefficient(w, T, P, f)
