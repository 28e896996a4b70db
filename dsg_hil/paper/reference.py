"""The paper's published numbers (Ma et al., Sections III.C and V.B), copied here so that the package and its
tests never need the paper itself."""

from __future__ import annotations

from dataclasses import dataclass

from ..results.thresholds import SAFETY_TEMPERATURE_C  # noqa: F401 - the paper's limit (Section IV), the metrics' too

__all__ = ["CREEP_MU_CH", "CREEP_P_CH_MPA", "CREEP_SLIP_TIME_S", "CREEP_TIME_S", "CREEP_T_CL_AT_FIRST_CH_LIMIT_C",
           "CREEP_T_ONCOMING_AT_STOP_C", "CREEP_T_START_C", "RIG_CASES", "RIG_DURATION_S", "RIG_T_START_C",
           "RigReference", "SAFETY_TEMPERATURE_C", "TOL_CREEP_MU", "TOL_CREEP_P_MPA", "TOL_CREEP_TIME_REL",
           "TOL_CREEP_T_C", "TOL_MU", "TOL_RISE_C", "TOL_SLIP_TIME_REL", "TOL_TORQUE_REL"]


@dataclass(frozen=True)
class RigReference:
    """One Section III.C case: 100 s at constant pressure and relative speed from 40 degC (Figs. 3-5)."""

    case: int
    pressure_mpa: float
    speed_rpm: float
    temperature_rise_c: float  # simulated rise after 100 s, Fig. 3
    torque_start_nm: float | None = None  # Fig. 4 (published for case 4 only)
    torque_end_nm: float | None = None
    mu_start: float | None = None  # Fig. 5 (published for case 4 only)
    mu_end: float | None = None
    T_end_c: float | None = None


RIG_T_START_C = 40.0
RIG_DURATION_S = 100.0

RIG_CASES: tuple[RigReference, ...] = (
    RigReference(1, 0.2, 150.0, 21.0),
    RigReference(2, 0.2, 300.0, 47.0),
    RigReference(3, 0.3, 150.0, 33.0),
    RigReference(4, 0.3, 300.0, 74.0, 149.5, 164.8, 0.054, 0.060, 114.0),
)

# Section V.B: the first CH slip (Figs. 10, 11).
CREEP_MU_CH = (0.063, 0.075)  # start, end
CREEP_P_CH_MPA = (0.75, 0.65)  # start, end
CREEP_T_START_C = 100.0  # both clutches start at 100 degC (CL heats 100 -> 250)

# Bands of the rig comparison, Section III.C (|simulated - published|).
TOL_RISE_C = 4.0
TOL_TORQUE_REL = 0.07
TOL_MU = 0.004

# Section V.B: the creep timeline (Figs. 8-12) and its bands.
CREEP_TIME_S = 174.0  # until the stop
CREEP_SLIP_TIME_S = {"CL": 43.5, "CH": 130.5}
CREEP_T_CL_AT_FIRST_CH_LIMIT_C = 205.5  # CL when CH first reaches 250 degC
CREEP_T_ONCOMING_AT_STOP_C = 246.0  # the on-coming CL when the vehicle stops
TOL_CREEP_TIME_REL = 0.10
TOL_SLIP_TIME_REL = 0.15
TOL_CREEP_T_C = 10.0
TOL_CREEP_MU = 0.005
TOL_CREEP_P_MPA = 0.05
