"""The TCU's own model of its two clutches, from what it can measure (pressure, shaft speeds, oil leaving each
clutch) and its calibration:

* friction coefficient mu(T, slip, P): an identified map standing for formula (6) (:class:`FrictionMap`);
* torque (5): M = mu * k_geom * P;
* plate temperature: one lumped node per clutch heated by the friction power (4) it estimates and cooled towards
  the measured temperature of the oil leaving that clutch,

      C dT/dt = mu(T, slip, P) k_geom P |slip| - K (T - T_oil_out),

  stepped exactly over each control period with the inputs held.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Callable

from dsg_hil.common.units import CV

from .calibration import Clutch, FrictionMap

__all__ = ["SLIP_FILTER_S", "friction_coefficient", "friction_heat", "heat_w", "mu_lookup", "nm_per_mpa",
           "plate_step", "pressure_for_torque", "slip_filter_weight", "torque_per_mpa"]

_MPA_TO_PA, _RPM_TO_RAD_S = CV.MPA_TO_PA, CV.RPM_TO_RAD_S
SLIP_FILTER_S = 0.1  # the slip behind a torque's pressure and the prediction's mu, low-passed: a 14-Hz ringing (70-ms
# period, aliased in the 10-ms samples) / 9, a launch's slip late by 0.1 s (about 6 of its 90 r/min)


MuLookup = Callable[[float, float, float], float]
_LOOKUPS: dict[int, tuple[FrictionMap, MuLookup]] = {}  # by id() of the map (hashing a map hashes all of mu)


def mu_lookup(m: FrictionMap) -> MuLookup:
    """``mu(T, |slip|, P)`` of the map ``m`` (T [degC], |slip| [r/min] >= 0, P [MPa]) as one function, built once per
    map (:func:`_build`): what :func:`friction_coefficient` evaluates, for a caller that writes the formulas out."""
    entry = _LOOKUPS.get(id(m))
    if entry is not None and entry[0] is m:
        return entry[1]
    if len(_LOOKUPS) >= 64:  # calibrations come and go (identify, tests): keep the cache small
        _LOOKUPS.clear()
    mu_of = _build(m)
    _LOOKUPS[id(m)] = (m, mu_of)
    return mu_of


_lookup = mu_lookup


def _build(m: FrictionMap) -> MuLookup:
    """``mu(T, |slip|, P)`` of the map ``m``. On each axis the index i and weight w of x between grid[i] and
    grid[i+1], clamped to the grid (i = 0, w = 0 below it; the last span, w = 1 above); the spans and each cell's
    four (T, slip) corners precomputed (the same subtractions and table entries, so the same floats), the map's
    tuples held in the closure. The last two lookups are remembered: a control cycle asks for the same state more
    than once (the monitor's bound, then the next prediction), and gets the very float again. (Apart from
    :func:`_lookup`: a function holding a closure makes its cells on every call.)"""
    T_grid, S_grid, P_grid, table = m.T_grid_c, m.slip_grid_rpm, m.P_grid_mpa, m.mu
    T_lo, T_hi, T_last, T_span = T_grid[0], T_grid[-1], len(T_grid) - 2, _spans(T_grid)
    S_lo, S_hi, S_last, S_span = S_grid[0], S_grid[-1], len(S_grid) - 2, _spans(S_grid)
    P_lo, P_hi, P_last, P_span = P_grid[0], P_grid[-1], len(P_grid) - 2, _spans(P_grid)
    corners = tuple(tuple((lo[j], lo[j + 1], hi[j], hi[j + 1]) for j in range(len(S_grid) - 1))
                    for lo, hi in zip(table, table[1:]))  # [i][j]: (T_i, S_j), (T_i, S_j+1), (T_i+1, S_j), ...
    last = before = (math.nan,) * 4  # (T, slip, P, mu) of the last two lookups (one tuple each: thread-safe)

    def mu_of(T_c: float, slip: float, P_mpa: float) -> float:  # the three axes written out: a call each costs more
        nonlocal last, before
        seen = last
        if seen[0] == T_c and seen[1] == slip and seen[2] == P_mpa:
            return seen[3]
        seen = before
        if seen[0] == T_c and seen[1] == slip and seen[2] == P_mpa:
            return seen[3]
        if T_c <= T_lo:
            i, wt = 0, 0.0
        elif T_c >= T_hi:
            i, wt = T_last, 1.0
        else:
            i = bisect_right(T_grid, T_c) - 1
            wt = (T_c - T_grid[i]) / T_span[i]
        if slip <= S_lo:
            j, ws = 0, 0.0
        elif slip >= S_hi:
            j, ws = S_last, 1.0
        else:
            j = bisect_right(S_grid, slip) - 1
            ws = (slip - S_grid[j]) / S_span[j]
        if P_mpa <= P_lo:
            k, wp = 0, 0.0
        elif P_mpa >= P_hi:
            k, wp = P_last, 1.0
        else:
            k = bisect_right(P_grid, P_mpa) - 1
            wp = (P_mpa - P_grid[k]) / P_span[k]
        a, b, c, d = corners[i][j]  # each interpolated in P, summed in this order
        k1 = k + 1
        vt, vs, vp = 1 - wt, 1 - ws, 1 - wp
        mu = (((0.0 + vt * vs * (vp * a[k] + wp * a[k1])) + vt * ws * (vp * b[k] + wp * b[k1]))
              + wt * vs * (vp * c[k] + wp * c[k1])) + wt * ws * (vp * d[k] + wp * d[k1])
        before, last = last, (T_c, slip, P_mpa, mu)
        return mu

    return mu_of


def _spans(grid: tuple[float, ...]) -> tuple[float, ...]:
    return tuple(grid[i + 1] - grid[i] for i in range(len(grid) - 1))


def nm_per_mpa(mu: float, c: Clutch) -> float:
    """Clutch torque per MPa of piston pressure [N m/MPa] at friction coefficient ``mu``, equation (5): mu k_geom."""
    return mu * c.k_geom_m3 * _MPA_TO_PA


def slip_filter_weight(dt: float) -> float:
    """Weight of a new slip sample after ``dt`` [s] in the first-order low-pass of :data:`SLIP_FILTER_S` (the
    controller's slip for the pressure and the prediction's mu, and its replay in ``identify``)."""
    return 1.0 - math.exp(-dt / SLIP_FILTER_S)


def pressure_for_torque(m: FrictionMap, c: Clutch, T_c: float, slip_rpm: float, torque_nm: float,
                        P_start: float) -> float:
    """Pressure [MPa] at which the clutch gives ``torque_nm`` by (5), M = mu(T, |slip|, P) k_geom P, with mu looked up
    at that pressure: on the map mu is linear in P between two nodes of its pressure axis, so M is a quadratic there,
    solved in closed form in the span where M crosses the torque. The search starts in the span of ``P_start`` (the
    last command) and steps towards the torque to the first span whose ends bracket it: where M rises with P (any
    loaded calibration's map: one whose M falls anywhere is refused, ``calibration.torque_falls``) that is the one
    crossing; on a map built otherwise, a crossing near the last command rather than the smallest. Clamped to the
    axis: 0 for no torque, the last node for more than it gives."""
    if torque_nm <= 0.0:
        return 0.0
    mu_of, grid, slip_rpm = _lookup(m), m.P_grid_mpa, abs(slip_rpm)
    target = torque_nm / (c.k_geom_m3 * _MPA_TO_PA)  # mu P [MPa] to reach
    last = len(grid) - 2
    k = min(max(bisect_right(grid, P_start) - 1, 0), last)
    step = 0
    while True:
        lo, hi = grid[k], grid[k + 1]
        mu_lo, mu_hi = mu_of(T_c, slip_rpm, lo), mu_of(T_c, slip_rpm, hi)
        if target < mu_lo * lo and k > 0 and step <= 0:
            k, step = k - 1, -1
        elif target > mu_hi * hi and k < last and step >= 0:
            k, step = k + 1, 1
        else:
            break
    if target >= mu_hi * hi:
        return hi if k == last else min(max(target / mu_hi, lo), hi)
    b = (mu_hi - mu_lo) / (hi - lo)  # mu = a + b P in the span: b P^2 + a P - target = 0
    a = mu_lo - b * lo
    disc = a * a + 4.0 * b * target
    P = 2.0 * target / (a + math.sqrt(disc)) if disc > 0.0 and a + math.sqrt(disc) > 0.0 else target / mu_lo
    return min(max(P, lo), hi)


def heat_w(mu: float, c: Clutch, P_mpa: float, slip_rpm: float) -> float:
    """Friction power into the plates [W] at friction coefficient ``mu``, pressure ``P_mpa`` >= 0 and slip
    ``slip_rpm`` >= 0, equation (4): torque (5) times slip speed, mu k_geom P |slip|. The one formula of the TCU's
    heat (predictor, monitor's bounds, handover margin); ``mu`` from :func:`mu_lookup` at the same state."""
    return mu * c.k_geom_m3 * _MPA_TO_PA * P_mpa * slip_rpm * _RPM_TO_RAD_S


def friction_coefficient(m: FrictionMap, T_c: float, slip_rpm: float, P_mpa: float) -> float:
    """mu from the map: trilinear in (T, |slip|, P), clamped at the edges (the four corners in (T, slip), each
    interpolated in P, summed in that order)."""
    return _lookup(m)(T_c, abs(slip_rpm), P_mpa)


def torque_per_mpa(m: FrictionMap, c: Clutch, T_c: float, slip_rpm: float, P_mpa: float) -> float:
    """Clutch torque per MPa of piston pressure [N m/MPa], equation (5), at the given state."""
    return nm_per_mpa(_lookup(m)(T_c, abs(slip_rpm), P_mpa), c)


def friction_heat(m: FrictionMap, c: Clutch, T_c: float, slip_rpm: float, P_mpa: float,
                  mu_slip_rpm: float | None = None) -> float:
    """Friction power into the plates [W], equation (4) (:func:`heat_w`) at the map's mu of that state, mu looked
    up at ``mu_slip_rpm`` if given: the predictor's slip low-passed as the controller's (a ringing output shaft,
    sampled every 10 ms, reads slips the friction never sees: it follows the slip with a lag)."""
    P = max(P_mpa, 0.0)
    slip = abs(slip_rpm)
    return heat_w(_lookup(m)(T_c, slip if mu_slip_rpm is None else abs(mu_slip_rpm), P), c, P, slip)


def plate_step(c: Clutch, T_c: float, heat_w: float, T_oil_c: float, dt: float) -> float:
    """Plate temperature after dt [s]: exact first-order step towards T_oil + Q/K."""
    T_inf = T_oil_c + heat_w / c.K_plate_oil_w_k
    return T_inf + (T_c - T_inf) * math.exp(-c.K_plate_oil_w_k * dt / c.C_plate_j_k)
