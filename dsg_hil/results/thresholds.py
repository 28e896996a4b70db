"""The thresholds that define the creep metrics (what counts as slipping, open, moving, stopped ...), and the TCU
states and clutches as TCU_STATUS codes them. Constants only: the paper's table (:mod:`dsg_hil.paper.reference`)
and a command's ``--help`` import them without numpy."""

from __future__ import annotations

__all__ = ["CLUTCHES", "ESTABLISHED", "MIN_PHASE_S", "P_ENGAGED", "SAFETY_TEMPERATURE_C", "SETTLE_S", "SLIP_MIN",
           "STATES", "STOP_MIN_S", "TORQUE_MIN", "V_MOVING"]

CLUTCHES = {1: "CL", 2: "CH"}
STATES = {0: "IDLE", 1: "ENGAGE", 2: "CREEP", 3: "HANDOVER", 4: "STOPPED_OVERHEAT", 5: "FAULT"}
SLIP_MIN = 0.5  # rad/s: below this a clutch counts as not slipping
TORQUE_MIN = 5.0  # N m: a clutch transmitting less is open
P_ENGAGED = 0.05e6  # Pa: with no truth torque known, a clutch above this pressure transmits
V_MOVING = 0.01  # m/s: slower counts as standing still
STOP_MIN_S = 2.0  # s at rest (creep requested) before the vehicle counts as stopped
MIN_PHASE_S = 0.5  # s: shorter runs of the driving clutch are not phases
SETTLE_S = 0.5  # s after a crossover (before the next) where a phase's start (end) values of mu and P are taken
SAFETY_TEMPERATURE_C = 250.0  # plate temperature limit of the creep strategy (the paper's, Section IV) [degC]
ESTABLISHED = 0.5  # creep is under way once the vehicle has reached this fraction of the desired speed
