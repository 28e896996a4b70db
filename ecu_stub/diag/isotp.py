"""ISO-TP (ISO 15765-2) server end as a small state machine: fed the tester's frames and the time, it returns the
frames to send; no bus, no clock.

Frames (N_PCI, first byte's high nibble): single frame 0 (length in the low nibble; CAN FD beyond 8 bytes: low
nibble 0 and the length in byte 1), first frame 1 (12-bit length; 0 then a 32-bit length beyond 4095), consecutive
frame 2 (sequence number 0-15, from 1), flow control 3 (flow status 0 continue / 1 wait / 2 overflow, block size,
STmin: 0-127 ms, 0xF1-0xF9 100-900 us, reserved values as 127 ms, ISO 15765-2 9.6.5.4).

It receives with one flow control (block size 0, STmin 0: send it all) and gives up a reception whose next
consecutive frame is later than N_Cr, a transmission whose flow control is later than N_Bs (1 s each, ISO
15765-2 table 16). It answers in the frame size the request came in: classic frames (8 bytes, padded) or CAN FD
(the request's length, at most 64). A malformed frame is counted and dropped, never raised.
"""

from __future__ import annotations

from collections.abc import Callable

from dsg_hil.common.errors import InputError

__all__ = ["FD_LENGTHS", "IsoTpServer"]

FD_LENGTHS = (8, 12, 16, 20, 24, 32, 48, 64)  # CAN FD data lengths (DLC 8-15)
N_CR_S = 1.0  # longest wait for the next consecutive frame [s]
N_BS_S = 1.0  # longest wait for a flow control [s]
WAIT_MAX = 10  # flow controls WAIT in a row before the transmission is given up (N_WFTmax)
PAD = 0xCC


def st_min_s(byte: int) -> float:
    """STmin byte of a flow control -> seconds (reserved values: 127 ms, ISO 15765-2 9.6.5.4)."""
    if byte <= 0x7F:
        return byte / 1000.0
    if 0xF1 <= byte <= 0xF9:
        return (byte - 0xF0) / 10000.0
    return 0.127


class IsoTpServer:
    """One ISO-TP link. :meth:`feed` takes a frame's data; complete requests go to ``deliver(payload, now)``;
    :meth:`send` starts a response; :meth:`poll` sends consecutive frames that wait for STmin. Each returns the
    frames to transmit (data bytes; more than 8: a CAN FD frame)."""

    def __init__(self, deliver: Callable[[bytes, float], None], max_length: int = 4095) -> None:
        if max_length < 1:
            raise InputError(f"IsoTpServer: max_length must be positive, not {max_length}")
        self.deliver, self.max_length = deliver, max_length
        self.frame_length = 8  # of the frames sent: the last request's (8 classic, more CAN FD)
        # reception: the payload so far, its length, the next sequence number, the deadline of the next CF
        self._rx: bytearray | None = None
        self._rx_length, self._rx_sn, self._rx_deadline = 0, 1, 0.0
        # transmission: what is left, the next sequence number, frames left in the block (0: unlimited), STmin,
        # the next CF's time, the flow control's deadline (None: not waiting for one), WAITs in a row
        self._tx = b""
        self._tx_sn, self._tx_block, self._tx_left, self._st_min = 1, 0, 0, 0.0
        self._tx_next = 0.0
        self._fc_deadline: float | None = None
        self._waits = 0
        self.dropped: dict[str, int] = {"malformed": 0, "sequence": 0, "timeout": 0, "overflow": 0, "unexpected": 0}

    @property
    def busy(self) -> bool:
        """A response is still being sent."""
        return bool(self._tx)

    # -- reception
    def feed(self, data: bytes, now: float) -> list[bytes]:
        """Take one frame of the tester's; returns the frames to send (flow control, consecutive frames)."""
        out = self.poll(now)
        if not data:
            return self._drop("malformed", out)
        kind = data[0] >> 4
        if kind == 3:
            return out + self._flow_control(data, now)
        if kind == 0:
            return self._single(data, now, out)
        if kind == 1:
            return self._first(data, now, out)
        if kind == 2:
            return self._consecutive(data, now, out)
        return self._drop("malformed", out)

    def _drop(self, why: str, out: list[bytes]) -> list[bytes]:
        self.dropped[why] += 1
        return out

    def _size_from(self, data: bytes) -> None:
        """Answer in the request's frame size: classic (<= 8 bytes) or its CAN FD length."""
        self.frame_length = 8 if len(data) <= 8 else min((n for n in FD_LENGTHS if n >= len(data)), default=64)

    def _single(self, data: bytes, now: float, out: list[bytes]) -> list[bytes]:
        length, start = data[0] & 0x0F, 1
        if length == 0 and len(data) > 8:  # CAN FD escape: the length in byte 1
            length, start = data[1], 2
        if length == 0 or start + length > len(data) or (start == 2 and length <= 7):
            return self._drop("malformed", out)
        self._rx = None  # a new request ends an unfinished one (ISO 15765-2 9.8.3)
        self._size_from(data)
        self._abort_tx()
        self.deliver(bytes(data[start:start + length]), now)
        return out

    def _first(self, data: bytes, now: float, out: list[bytes]) -> list[bytes]:
        if len(data) < 8:
            return self._drop("malformed", out)
        length, start = ((data[0] & 0x0F) << 8) | data[1], 2
        if length == 0:
            if len(data) < 6:
                return self._drop("malformed", out)
            length, start = int.from_bytes(data[2:6], "big"), 6
        single_max = 7 if len(data) <= 8 else len(data) - 2
        if length <= single_max:
            return self._drop("malformed", out)
        self._size_from(data)
        self._abort_tx()
        if length > self.max_length:
            self._rx = None
            self.dropped["overflow"] += 1
            return [*out, self._pad(bytes((0x32, 0, 0)))]  # flow status overflow
        self._rx = bytearray(data[start:])
        self._rx_length, self._rx_sn, self._rx_deadline = length, 1, now + N_CR_S
        return [*out, self._pad(bytes((0x30, 0, 0)))]  # continue to send, block size 0, STmin 0

    def _consecutive(self, data: bytes, now: float, out: list[bytes]) -> list[bytes]:
        rx = self._rx
        if rx is None:
            return self._drop("unexpected", out)
        if now > self._rx_deadline:
            self._rx = None
            return self._drop("timeout", out)
        if data[0] & 0x0F != self._rx_sn:  # a wrong sequence number ends the reception (ISO 15765-2 9.8.3)
            self._rx = None
            return self._drop("sequence", out)
        rx += data[1:]
        self._rx_sn = (self._rx_sn + 1) & 0x0F
        self._rx_deadline = now + N_CR_S
        if len(rx) >= self._rx_length:
            self._rx = None
            self.deliver(bytes(rx[: self._rx_length]), now)
        return out

    # -- transmission
    def send(self, payload: bytes, now: float) -> list[bytes]:
        """Start sending ``payload``: a single frame, or a first frame (the rest after the tester's flow control)."""
        self._abort_tx()
        n, size = len(payload), self.frame_length
        if n <= 7 or (size > 8 and n <= size - 2):
            head = bytes((n,)) if n <= 7 else bytes((0, n))
            return [self._pad(head + payload)]
        head = bytes((0x10 | (n >> 8), n & 0xFF)) if n <= 4095 else bytes((0x10, 0)) + n.to_bytes(4, "big")
        first = size - len(head)
        self._tx, self._tx_sn = payload[first:], 1
        self._fc_deadline, self._waits = now + N_BS_S, 0
        return [head + payload[:first]]

    def _abort_tx(self) -> None:
        self._tx, self._fc_deadline = b"", None

    def _flow_control(self, data: bytes, now: float) -> list[bytes]:
        if self._fc_deadline is None or not self._tx:
            self.dropped["unexpected"] += 1
            return []
        if len(data) < 3:
            self.dropped["malformed"] += 1
            return []
        status = data[0] & 0x0F
        if status == 1:  # wait
            self._waits += 1
            if self._waits > WAIT_MAX:
                self._abort_tx()
                self.dropped["timeout"] += 1
            else:
                self._fc_deadline = now + N_BS_S
            return []
        if status != 0:  # overflow (or reserved): the tester cannot take it
            self._abort_tx()
            self.dropped["overflow"] += 1
            return []
        self._fc_deadline = None
        self._tx_block, self._tx_left, self._st_min = data[1], data[1], st_min_s(data[2])
        self._tx_next = now
        return self.poll(now)

    def poll(self, now: float) -> list[bytes]:
        """Consecutive frames due by ``now``; timeouts."""
        if self._rx is not None and now > self._rx_deadline:
            self._rx = None
            self.dropped["timeout"] += 1
        if not self._tx:
            return []
        if self._fc_deadline is not None:
            if now > self._fc_deadline:
                self._abort_tx()
                self.dropped["timeout"] += 1
            return []
        out = []
        step = self.frame_length - 1
        while self._tx and now >= self._tx_next:
            chunk, self._tx = self._tx[:step], self._tx[step:]
            frame = bytes((0x20 | self._tx_sn,)) + chunk
            out.append(self._pad(frame) if self._tx or self.frame_length == 8 else self._pad_fd(frame))
            self._tx_sn = (self._tx_sn + 1) & 0x0F
            if self._st_min > 0.0:
                self._tx_next = now + self._st_min
            if self._tx and self._tx_block:
                self._tx_left -= 1
                if self._tx_left == 0:  # block done: wait for the next flow control
                    self._fc_deadline = now + N_BS_S
                    break
        return out

    def _pad(self, frame: bytes) -> bytes:
        """Classic frames padded to 8 bytes; CAN FD to the link's frame length."""
        size = 8 if len(frame) <= 8 and self.frame_length == 8 else self.frame_length
        return frame + bytes((PAD,)) * (size - len(frame))

    def _pad_fd(self, frame: bytes) -> bytes:
        """The last consecutive frame of a CAN FD link: the shortest FD length that holds it."""
        size = min(n for n in FD_LENGTHS if n >= len(frame)) if len(frame) > 8 else 8
        return frame + bytes((PAD,)) * (size - len(frame))
