"""The TCU's plate temperature predictor: one lumped node per clutch, heated by the friction power it estimates
from what it can see, cooled towards the measured temperature of the oil leaving that clutch.

    C dT/dt = mu_nom k_geom P_meas |slip| - K (T - T_oil_out)

Solved exactly over each step with the inputs held.
"""

from __future__ import annotations

import math

from .calibration import TcuCalibration


def heat_estimate(P_mpa: float, slip_rpm: float, cal: TcuCalibration) -> float:
    """Estimated friction power [W] from measured pressure [MPa] and slip [r/min]."""
    return cal.mu_nom * cal.k_geom_m3 * max(P_mpa, 0.0) * 1e6 * abs(slip_rpm) * 2.0 * math.pi / 60.0


def predict_step(T_c: float, heat_w: float, T_oil_c: float, dt: float, cal: TcuCalibration) -> float:
    """Plate temperature after dt [s] (exact first-order step)."""
    T_inf = T_oil_c + heat_w / cal.K_plate_oil_w_k
    return T_inf + (T_c - T_inf) * math.exp(-cal.K_plate_oil_w_k * dt / cal.C_plate_j_k)
