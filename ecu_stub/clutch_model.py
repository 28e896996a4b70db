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

from .calibration import Clutch, FrictionMap

RPM_TO_RAD_S = 2.0 * math.pi / 60.0


def friction_coefficient(m: FrictionMap, T_c: float, slip_rpm: float, P_mpa: float) -> float:
    """mu from the map: trilinear in (T, |slip|, P), clamped at the edges. On each axis the index i and weight w
    of x between grid[i] and grid[i+1] (written out three times: four calls a control period, the TCU's costliest
    arithmetic; the same operations in the same order as ever, so the same floats)."""
    grid = m.T_grid_c
    if T_c <= grid[0]:
        i, wt = 0, 0.0
    elif T_c >= grid[-1]:
        i, wt = len(grid) - 2, 1.0
    else:
        i = bisect_right(grid, T_c) - 1
        wt = (T_c - grid[i]) / (grid[i + 1] - grid[i])
    grid, x = m.slip_grid_rpm, abs(slip_rpm)
    if x <= grid[0]:
        j, ws = 0, 0.0
    elif x >= grid[-1]:
        j, ws = len(grid) - 2, 1.0
    else:
        j = bisect_right(grid, x) - 1
        ws = (x - grid[j]) / (grid[j + 1] - grid[j])
    grid = m.P_grid_mpa
    if P_mpa <= grid[0]:
        k, wp = 0, 0.0
    elif P_mpa >= grid[-1]:
        k, wp = len(grid) - 2, 1.0
    else:
        k = bisect_right(grid, P_mpa) - 1
        wp = (P_mpa - grid[k]) / (grid[k + 1] - grid[k])
    lo, hi = m.mu[i], m.mu[i + 1]  # the four corners in (T, slip), each interpolated in P; summed in this order
    a, b, c, d = lo[j], lo[j + 1], hi[j], hi[j + 1]
    vt, vs, vp = 1 - wt, 1 - ws, 1 - wp
    k1 = k + 1
    return (((0.0 + vt * vs * (vp * a[k] + wp * a[k1])) + vt * ws * (vp * b[k] + wp * b[k1]))
            + wt * vs * (vp * c[k] + wp * c[k1])) + wt * ws * (vp * d[k] + wp * d[k1])


def torque_per_mpa(m: FrictionMap, c: Clutch, T_c: float, slip_rpm: float, P_mpa: float) -> float:
    """Clutch torque per MPa of piston pressure [N m/MPa], equation (5), at the given state."""
    return friction_coefficient(m, T_c, slip_rpm, P_mpa) * c.k_geom_m3 * 1e6


def friction_heat(m: FrictionMap, c: Clutch, T_c: float, slip_rpm: float, P_mpa: float) -> float:
    """Friction power into the plates [W], equation (4): torque (5) times slip speed."""
    P = max(P_mpa, 0.0)  # torque_per_mpa written out (the same products in the same order)
    return friction_coefficient(m, T_c, slip_rpm, P) * c.k_geom_m3 * 1e6 * P * abs(slip_rpm) * RPM_TO_RAD_S


def plate_step(c: Clutch, T_c: float, heat_w: float, T_oil_c: float, dt: float) -> float:
    """Plate temperature after dt [s]: exact first-order step towards T_oil + Q/K."""
    T_inf = T_oil_c + heat_w / c.K_plate_oil_w_k
    return T_inf + (T_c - T_inf) * math.exp(-c.K_plate_oil_w_k * dt / c.C_plate_j_k)
