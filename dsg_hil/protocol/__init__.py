"""The CAN protocol shared by the plant and the TCU: DBC loading, codec with counters and CRC, RX validity.

Knows nothing of physics. The DBC is the single source of truth for names, scaling, ranges and cycle times.
"""

from .codec import Codec, DecodedFrame, FrameError, ProtocolError, load_dbc
from .crc import crc8_j1850
from .validity import RxMonitor, RxState, TxScheduler

__all__ = ["Codec", "DecodedFrame", "FrameError", "ProtocolError", "RxMonitor", "RxState", "TxScheduler",
           "crc8_j1850", "load_dbc"]
