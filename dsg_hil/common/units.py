"""Unit conversions in one place, as opendbc's ``CV``: dsg-hil and ecu-stub compute in SI (rad/s, Pa, J, W, s; and
degC for temperatures, as the paper); the other units live at the edges only: the DBC's signals (r/min, MPa, %),
the paper's formula (6) (r/min, MPa), the JSON summary and the figures (MPa, kJ, kW, ms).

``A_TO_B``: a value in A times it is the value in B. Each inverse is ``1 / forward``; every pair here is exact both
ways where the code relies on it (``RPM_TO_RAD_S`` is 2 pi / 60 to the last bit). Standard library only: ecu-stub
imports it.
"""

from __future__ import annotations

import math

__all__ = ["CV"]


class CV:
    """Conversion factors (a namespace of constants, never instantiated)."""

    # angular speed
    RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
    RPM_TO_RAD_S = 1.0 / RAD_S_TO_RPM

    # pressure
    MPA_TO_PA = 1e6
    PA_TO_MPA = 1.0 / MPA_TO_PA
    KPA_TO_PA = 1e3
    BAR_TO_PA = 1e5

    # speed
    KMH_TO_MPS = 1.0 / 3.6
    MPS_TO_KMH = 3.6

    # temperature (an offset: a value in K less this is the value in degC)
    ZERO_C_IN_K = 273.15

    # energy and power
    KJ_TO_J = 1e3
    J_TO_KJ = 1.0 / KJ_TO_J
    KW_TO_W = 1e3
    W_TO_KW = 1.0 / KW_TO_W

    # time
    S_TO_MS = 1e3
    MS_TO_S = 1.0 / S_TO_MS

    # ratio
    FRACTION_TO_PERCENT = 100.0
    PERCENT_TO_FRACTION = 1.0 / FRACTION_TO_PERCENT
