"""A direct in-process bus: two ends, each frame sent on one received on the other, for the plant and a TCU in
one process in lockstep (:func:`dsg_hil.sim.loop.run_closed_loop`, ``dsg-hil run`` on ``virtual``).

It does for two nodes what python-can's ``virtual`` interface does (the receiver gets its own copy of the frame,
stamped with the wall-clock time it was received, ``is_rx`` set, on the bus's channel), without what costs
there: a ``deepcopy`` of every frame and a locked ``queue.Queue`` per receiver. Receiving with a timeout waits
on a condition, so a sender in another thread wakes it; in one process nothing else ever waits.

A classic data frame with an 11-bit ID travels as its ID and data alone (``bytes``: neither side can change
the other's frame), and a node that knows this bus hands those over directly, with no :class:`can.Message`
built for them at all (:meth:`LocalBus.send_data`, :meth:`LocalBus.recv_data`: the plant's and ecu-stub's
lock-step hot path, which builds a message only for a listener); ``recv`` builds the message python-can's
``virtual`` would have delivered. Any other frame sent as a message (remote, error, CAN FD, 29-bit ID) travels as
a copy of it. A node that sends a CAN FD message's frames by ``send_data`` (the plant and ecu-stub do: both ends
know the matrix) hands them over as (ID, data) too, and the receiving node takes them in its message's format
(:attr:`.codec.Codec.fd`); ``recv`` gives such a frame as a classic one.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Iterable

import can

from .frame import data_frame

__all__ = ["LocalBus", "local_pair"]

_FIELDS = ("arbitration_id", "is_extended_id", "is_remote_frame", "is_error_frame", "dlc", "data", "is_fd",
           "bitrate_switch", "error_state_indicator")


def local_pair(channel: str = "local") -> tuple[LocalBus, LocalBus]:
    """Two connected ends of one in-process bus."""
    a, b = LocalBus(channel), LocalBus(channel)
    a.peer, b.peer = b, a
    return a, b


class LocalBus(can.BusABC):
    """One end of :func:`local_pair`: ``send``, ``recv`` and ``shutdown`` as python-can's buses have them."""

    def __init__(self, channel: str) -> None:
        self._queue: deque[tuple[int, bytes] | can.Message] = deque()
        self._ready = threading.Condition()
        self._waiting = False
        self.peer: LocalBus | None = None
        self.channel = channel
        self.channel_info = f"in-process bus {channel}"
        super().__init__(channel=channel)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.is_remote_frame or msg.is_error_frame or msg.is_fd or msg.is_extended_id:  # copied the slow way
            copy = can.Message(**{name: getattr(msg, name) for name in _FIELDS}, channel=self.channel, is_rx=True,
                               timestamp=time.time())
            copy.data = bytearray(msg.data)  # never shared
            self._put(copy)
        else:
            self._put((msg.arbitration_id, bytes(msg.data)))

    def send_data(self, frame_id: int, data: bytes) -> None:
        """Send a classic data frame with an 11-bit ID: ``send`` of ``data_frame(frame_id, data)``, cheaper."""
        self._put((frame_id, data))

    def send_all(self, frames: Iterable[tuple[int, bytes]]) -> None:
        """:meth:`send_data` of each of ``frames`` (ID, data) in turn, in one call."""
        if self._is_shutdown:
            raise can.CanOperationError("Cannot operate on a closed bus")
        peer = self.peer
        if peer is None or peer._is_shutdown:
            return
        peer._queue.extend(frames)
        if peer._waiting:
            with peer._ready:
                peer._ready.notify_all()

    def _put(self, item: tuple[int, bytes] | can.Message) -> None:
        if self._is_shutdown:
            raise can.CanOperationError("Cannot operate on a closed bus")
        peer = self.peer
        if peer is None or peer._is_shutdown:  # nobody listening: the frame is gone, as on a bus
            return
        peer._queue.append(item)
        if peer._waiting:
            with peer._ready:
                peer._ready.notify_all()

    def recv(self, timeout: float | None = None) -> can.Message | None:
        item = self.recv_data(timeout)
        if isinstance(item, tuple):
            return data_frame(item[0], item[1], time.time(), self.channel, True)
        return item

    def recv_data(self, timeout: float | None = None) -> tuple[int, bytes] | can.Message | None:
        """``recv`` without building a message for a classic data frame with an 11-bit ID: (ID, data) for one,
        the message for any other frame, None when none came within ``timeout``."""
        if self._is_shutdown:
            raise can.CanOperationError("Cannot operate on a closed bus")
        if self._queue:
            return self._queue.popleft()
        if timeout is not None and timeout <= 0:
            return None
        end = None if timeout is None else time.monotonic() + timeout
        with self._ready:
            self._waiting = True  # set before the queue is looked at again: a sender then notifies
            try:
                while not self._queue:
                    remaining = None if end is None else end - time.monotonic()
                    if remaining is not None and remaining <= 0:
                        return None
                    self._ready.wait(remaining)
                return self._queue.popleft()
            finally:
                self._waiting = False

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.recv(timeout), False

    def shutdown(self) -> None:
        super().shutdown()
        self._queue.clear()
