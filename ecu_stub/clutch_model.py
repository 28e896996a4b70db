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

from dsg_hil.common.units import CV

from .calibration import Clutch, FrictionMap

__all__ = ["friction_coefficient", "friction_heat", "plate_step", "torque_per_mpa"]


def _locate(grid: tuple[float, ...], x: float) -> tuple[int, float]:
    """Index i and weight w of x between grid[i] and grid[i+1], clamped to the grid."""
    if x <= grid[0]:
        return 0, 0.0
    if x >= grid[-1]:
        return len(grid) - 2, 1.0
    i = bisect_right(grid, x) - 1
    return i, (x - grid[i]) / (grid[i + 1] - grid[i])


def friction_coefficient(m: FrictionMap, T_c: float, slip_rpm: float, P_mpa: float) -> float:
    """mu from the map: trilinear in (T, |slip|, P), clamped at the edges."""
    i, wt = _locate(m.T_grid_c, T_c)
    j, ws = _locate(m.slip_grid_rpm, abs(slip_rpm))
    k, wp = _locate(m.P_grid_mpa, P_mpa)
    lo, hi = m.mu[i], m.mu[i + 1]  # the four corners in (T, slip), each interpolated in P; summed in this order
    a, b, c, d = lo[j], lo[j + 1], hi[j], hi[j + 1]
    vt, vs, vp = 1 - wt, 1 - ws, 1 - wp
    mu = 0.0
    mu += vt * vs * (vp * a[k] + wp * a[k + 1])
    mu += vt * ws * (vp * b[k] + wp * b[k + 1])
    mu += wt * vs * (vp * c[k] + wp * c[k + 1])
    mu += wt * ws * (vp * d[k] + wp * d[k + 1])
    return mu


def torque_per_mpa(m: FrictionMap, c: Clutch, T_c: float, slip_rpm: float, P_mpa: float) -> float:
    """Clutch torque per MPa of piston pressure [N m/MPa], equation (5), at the given state."""
    return friction_coefficient(m, T_c, slip_rpm, P_mpa) * c.k_geom_m3 * CV.MPA_TO_PA


def friction_heat(m: FrictionMap, c: Clutch, T_c: float, slip_rpm: float, P_mpa: float) -> float:
    """Friction power into the plates [W], equation (4): torque (5) times slip speed."""
    P = max(P_mpa, 0.0)
    return torque_per_mpa(m, c, T_c, slip_rpm, P) * P * abs(slip_rpm) * CV.RPM_TO_RAD_S


def plate_step(c: Clutch, T_c: float, heat_w: float, T_oil_c: float, dt: float) -> float:
    """Plate temperature after dt [s]: exact first-order step towards T_oil + Q/K."""
    T_inf = T_oil_c + heat_w / c.K_plate_oil_w_k
    return T_inf + (T_c - T_inf) * math.exp(-c.K_plate_oil_w_k * dt / c.C_plate_j_k)
