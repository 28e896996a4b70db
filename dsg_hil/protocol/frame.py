"""A :class:`can.Message` built without python-can's argument checks, for the frames this package builds and
copies on its hot path (a lock-step period builds about ten): the same attributes as ``can.Message(...)`` gives a
data frame of ``data``, at a fifth of the cost; a CAN FD frame where the matrix says its ID is one (``fd``: by
frame ID, its bit-rate switch), a classic one otherwise.

CAN FD carries 0-8, 12, 16, 20, 24, 32, 48 or 64 bytes (:data:`FD_LENGTHS`, the lengths a DLC codes):
:func:`fd_length` snaps a message's length to the frame that carries it."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import can

__all__ = ["FD_LENGTHS", "FrameListener", "data_frame", "fd_length"]

FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)  # the data lengths of CAN FD's DLC codes 0..15

# What a run tells every frame it took or sent (a log writer, a can.Listener, a list's append): any callable of a
# frame. The runners keep a sequence of them (a tuple or a list alike).
FrameListener = Callable[[can.Message], object]

_Message = can.Message
_new = _Message.__new__


def data_frame(arbitration_id: int, data: bytes | bytearray, timestamp: float = 0.0, channel: str | None = None,
               is_rx: bool = False, is_extended_id: bool = False, fd: Mapping[int, bool] | None = None) -> can.Message:
    """``can.Message(arbitration_id=..., data=..., is_extended_id=..., dlc=len(data), timestamp=..., channel=...,
    is_rx=...)`` for a classic CAN data frame (at most 8 bytes: not checked here); a CAN FD one (``is_fd``,
    ``bitrate_switch`` as ``fd`` gives it) where ``arbitration_id`` is in ``fd`` (a codec's :attr:`fd`)."""
    msg = _new(_Message)
    msg.timestamp = timestamp
    msg.arbitration_id = arbitration_id
    msg.is_extended_id = is_extended_id
    msg.is_remote_frame = False
    msg.is_error_frame = False
    msg.channel = channel
    msg.dlc = len(data)
    msg.data = bytearray(data)
    brs = fd.get(arbitration_id) if fd else None
    msg.is_fd = brs is not None
    msg.is_rx = is_rx
    msg.bitrate_switch = bool(brs)
    msg.error_state_indicator = False
    return msg


def fd_length(length: int) -> int:
    """The data length of the CAN FD frame that carries ``length`` bytes: the next of :data:`FD_LENGTHS`
    (ValueError above 64)."""
    for n in FD_LENGTHS:
        if n >= length:
            return n
    raise ValueError(f"a CAN FD frame carries at most 64 bytes, not {length}")
