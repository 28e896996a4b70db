"""Clutch friction: torque (5) and friction coefficient (6) of the paper.

Formula (6) is garbled in the source text. Read literally, its first term raises a negative number to the power
-5.16 and has no real value. This module uses the *Stribeck reading* of that term::

    mu = A * exp(-(0.028574 n / D) ** 5.16)                         (boost near zero slip, 0 where D <= 0)
       + 0.01 ln(0.04398 n + 1) / exp(0.005 T)
       + 0.08 (exp(-0.005 T) - 1)(exp(-0.0022 n) - 1)
       - 0.005 ln(28.3 P) + 0.035

    D = (ln T - 3.2)(28.3 P) ** 0.4 - 0.87

with ``n`` the slip speed in r/min, ``T`` the plate temperature in degC and ``P`` the pressure in MPa, as the paper
prints them. The printed prefactor 23 gives mu >> 1 below about 150 r/min in every reading tried, so ``A`` is a
calibrated parameter (``friction.A_stribeck`` in the parameter file, with its target). See
docs/explanation/model.md, "Formula (6)".

Units: the fitted coefficients are kept as the paper prints them (0.028574, 0.04398 and 0.0022 per r/min; 28.3 per
MPa); the functions here take SI (slip speed in rad/s, pressure in Pa, as every caller has them) and convert to
(6)'s units once, at their top (:class:`dsg_hil.common.units.CV`), so the plant computes the same numbers to the
last bit as when its callers converted.

Frictional memory: the plant feeds (6) a first-order lag of the slip speed magnitude (``tau_slip``), not the
instantaneous slip; see :func:`slip_memory_step`.

Compiled (:mod:`dsg_hil.physics.jit`): (6) and the slip memory, which the plant evaluates every step.

Guards (stated, not hidden): ``P`` is floored at ``P_floor`` inside (6) only, because ``-0.005 ln(28.3 P)`` is
unbounded as ``P -> 0`` (the torque (5) still uses the true pressure, so zero pressure gives zero torque);
``T <= 1 degC`` or ``D <= 0`` switches the first term off; ``n`` is the magnitude of the slip speed.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..common.units import CV
from .jit import compiled
from .params import ClutchGeometry, Friction

__all__ = ["clutch_torque_capacity", "friction_coefficient", "friction_coefficient_at", "friction_coefficient_grid",
           "mean_friction_radius", "pressure_factors", "slip_memory_relax", "slip_memory_step", "stribeck_term",
           "torque_per_mu"]

# (6)'s units (module constants: the compiled code reads them as constants)
_RPM_PER_RAD_S = CV.RAD_S_TO_RPM
_PA_PER_MPA = CV.MPA_TO_PA


def mean_friction_radius(R_i: float, R_o: float) -> float:
    """Effective friction radius of an annulus [m]: 2/3 (R_o^3 - R_i^3)/(R_o^2 - R_i^2), from (5)."""
    return 2.0 / 3.0 * (R_o**3 - R_i**3) / (R_o**2 - R_i**2)


def torque_per_mu(geometry: ClutchGeometry, pressure_pa: float) -> float:
    """Clutch torque per unit friction coefficient [N*m]: N * P * A_f * r_m, from (5)."""
    return geometry.N * max(pressure_pa, 0.0) * geometry.A_f * mean_friction_radius(geometry.R_i, geometry.R_o)


def clutch_torque_capacity(mu: float, geometry: ClutchGeometry, pressure_pa: float) -> float:
    """Friction torque magnitude of a slipping clutch, equation (5) [N*m]."""
    return mu * torque_per_mu(geometry, pressure_pa)


@compiled
def pressure_factors(P: float, f: Friction) -> tuple[float, float]:
    """The parts of (6) that depend on the pressure alone, ``((28.3 P) ** 0.4, 0.005 ln(28.3 P))`` with P [Pa]
    in MPa, floored at ``P_floor``: a plant step whose pressure has not changed reuses them (two pow/log fewer)."""
    P_mpa = max(P / _PA_PER_MPA, f.P_floor / _PA_PER_MPA)
    return (28.3 * P_mpa) ** 0.4, 0.005 * math.log(28.3 * P_mpa)


@compiled
def stribeck_term(slip_speed: float, T_c: float, P: float, f: Friction) -> float:
    """First term of (6) in the Stribeck reading (see module docstring); zero where D <= 0 or T <= 1 degC.

    slip_speed [rad/s] (sign ignored); T_c: plate temperature [degC]; P: pressure [Pa]."""
    return _stribeck_rpm(abs(slip_speed * _RPM_PER_RAD_S), T_c, pressure_factors(P, f)[0], f)


@compiled
def _stribeck_rpm(n: float, T_c: float, P_factor: float, f: Friction) -> float:
    """:func:`stribeck_term` in (6)'s units: ``n`` = |slip speed| [r/min], ``P_factor = (28.3 P) ** 0.4``."""
    if T_c <= 1.0:
        return 0.0
    D = (math.log(T_c) - 3.2) * P_factor - 0.87
    if D <= 0.0:
        return 0.0
    ratio = 0.028574 * n / D
    if ratio > 4.0:  # exp(-(ratio ** 5.16)) < exp(-1286) underflows to exactly 0: skip the power and exponential
        return 0.0
    return f.A_stribeck * math.exp(-(ratio**5.16))


@compiled
def friction_coefficient(slip_speed: float, T_c: float, P: float, f: Friction) -> float:
    """Friction coefficient mu of the wet paper/steel pair, equation (6) in the Stribeck reading.

    slip_speed [rad/s] (sign ignored); T_c: plate temperature [degC]; P: pressure [Pa].
    """
    P_factor, P_log = pressure_factors(P, f)
    return friction_coefficient_at(slip_speed, T_c, P_factor, P_log, f)


@compiled
def friction_coefficient_at(slip_speed: float, T_c: float, P_factor: float, P_log: float, f: Friction) -> float:
    """:func:`friction_coefficient` given the pressure's parts of (6) (:func:`pressure_factors`)."""
    n = abs(slip_speed * _RPM_PER_RAD_S)  # (6) in r/min
    exp_T = math.exp(-0.005 * T_c)  # = 1 / exp(0.005 T): one exponential for both terms
    return (
        _stribeck_rpm(n, T_c, P_factor, f)
        + 0.01 * math.log(0.04398 * n + 1.0) * exp_T
        + 0.08 * (exp_T - 1.0) * (math.exp(-0.0022 * n) - 1.0)
        - P_log
        + 0.035
    )


def friction_coefficient_grid(slip_speed: ArrayLike, T_c: ArrayLike, P: ArrayLike, f: Friction) -> np.ndarray:
    """:func:`friction_coefficient` over broadcast arrays (for maps and tests): slip speed [rad/s], T [degC],
    P [Pa]."""
    return np.vectorize(lambda w, T, p: friction_coefficient(w, T, p, f), otypes=[float])(slip_speed, T_c, P)


@compiled
def slip_memory_step(slip_memory: float, slip_speed: float, dt: float, f: Friction) -> float:
    """Exact step of tau_slip * s' = |slip_speed| - s with the slip held over dt (any speed unit)."""
    return slip_memory_relax(slip_memory, slip_speed, math.exp(-dt / f.tau_slip))


@compiled
def slip_memory_relax(slip_memory: float, slip_speed: float, decay: float) -> float:
    """:func:`slip_memory_step` given ``decay = exp(-dt / tau_slip)`` (a loop of steps of one dt computes it once)."""
    target = abs(slip_speed)
    return target + (slip_memory - target) * decay
