"""The CAN protocol shared by the plant and the TCU: DBC loading, codec with counters and CRC, RX validity.

Knows nothing of physics. The DBC is the single source of truth for names, scaling, ranges and cycle times.
The names below are imported when first used (PEP 562), so that a command's ``--help`` and :mod:`.errors` do not
load cantools and python-can.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..common.lazy import lazy_names

if TYPE_CHECKING:
    from .codec import Codec, DecodedFrame, FrameError, ProtocolError, load_dbc
    from .crc import crc8_j1850
    from .e2e import MAX_DELTA, Protection, ProtectionError
    from .profiles import FrameProtection, ProtectionSpec
    from .validity import RxMonitor, RxState, TxScheduler

_WHERE = {"Codec": "codec", "DecodedFrame": "codec", "FrameError": "codec", "ProtocolError": "codec",
          "load_dbc": "codec", "crc8_j1850": "crc", "MAX_DELTA": "e2e", "Protection": "e2e", "ProtectionError": "e2e",
          "FrameProtection": "profiles", "ProtectionSpec": "profiles", "RxMonitor": "validity", "RxState": "validity",
          "TxScheduler": "validity"}

__all__ = ["MAX_DELTA", "Codec", "DecodedFrame", "FrameError", "FrameProtection", "Protection", "ProtectionError",
           "ProtectionSpec", "ProtocolError", "RxMonitor", "RxState", "TxScheduler", "crc8_j1850", "load_dbc"]


__getattr__ = lazy_names(__name__, _WHERE, globals())
