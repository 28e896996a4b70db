"""Clutch pressure response: a first-order lag towards the command clamped to [0, P_max].

With no valid command the valve is unpowered: the command is 0 and the pressure decays (return springs open the
clutch). Solved exactly over a step with the command held.
"""

from __future__ import annotations

import math

from .jit import compiled
from .params import Hydraulics

__all__ = ["clamp_command", "pressure_relax", "pressure_step"]


@compiled
def clamp_command(P_cmd: float, h: Hydraulics) -> float:
    """The pressure the valve can actually aim for [Pa]."""
    if not math.isfinite(P_cmd):
        return 0.0
    return min(max(P_cmd, 0.0), h.P_max)


@compiled
def pressure_step(P: float, P_cmd: float, dt: float, h: Hydraulics) -> float:
    """Pressure after dt [s] from P [Pa] with the command held: exact solution of tau P' = P_cmd - P."""
    return pressure_relax(P, P_cmd, math.exp(-dt / h.tau), h)


@compiled
def pressure_relax(P: float, P_cmd: float, decay: float, h: Hydraulics) -> float:
    """:func:`pressure_step` given ``decay = exp(-dt / tau)`` (a loop of steps of one dt computes it once)."""
    target = clamp_command(P_cmd, h)
    return target + (P - target) * decay
