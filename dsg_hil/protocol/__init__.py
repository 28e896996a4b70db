"""The CAN protocol shared by the plant and the TCU: DBC loading, codec with counters and CRC, RX validity.

Knows nothing of physics. The DBC is the single source of truth for names, scaling, ranges and cycle times.
"""

from .codec import Codec, DecodedFrame, FrameError, ProtocolError, load_dbc
from .crc import crc8_j1850
from .e2e import MAX_DELTA, Protection, ProtectionError
from .validity import RxMonitor, RxState, TxScheduler

__all__ = ["MAX_DELTA", "Codec", "DecodedFrame", "FrameError", "Protection", "ProtectionError", "ProtocolError",
           "RxMonitor", "RxState", "TxScheduler", "crc8_j1850", "load_dbc"]
