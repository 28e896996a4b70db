"""Engine with an idle governor. The paper gives no engine map: a flat full-load curve and a PI governor.

The governor holds a speed setpoint (idle unless raised) with fuel torque limited to [0, full load]; the net
torque of (7) is fuel torque minus drag. The integrator stops while the output saturates (anti-windup).
"""

from __future__ import annotations

from .jit import compiled
from .params import Engine

__all__ = ["full_load_torque", "governor", "net_torque"]


@compiled
def full_load_torque(omega_e: float, e: Engine) -> float:
    """Full-load fuel torque [N m]: M_max up to omega_rated, falling linearly to zero at 1.2 omega_rated."""
    if omega_e <= e.omega_rated:
        return e.M_max
    return max(0.0, e.M_max * (1.0 - (omega_e - e.omega_rated) / (0.2 * e.omega_rated)))


@compiled
def governor(omega_e: float, integral: float, setpoint: float, e: Engine) -> tuple[float, float]:
    """Fuel torque [N m] and the integral's rate [N m/s] for engine speed omega_e [rad/s].

    ``integral`` is the governor's integral term [N m]; it starts at M_drag so that idle is held without load.
    """
    error = setpoint - omega_e
    raw = e.Kp_gov * error + integral
    limit = full_load_torque(omega_e, e)
    fuel = min(max(raw, 0.0), limit)
    saturated = (raw > limit and error > 0.0) or (raw < 0.0 and error < 0.0)
    return fuel, 0.0 if saturated else e.Ki_gov * error


@compiled
def net_torque(fuel: float, e: Engine) -> float:
    """Net engine torque M_e of (7) [N m]: fuel torque minus drag."""
    return fuel - e.M_drag
