"""Per-message receive validity (deadline from the DBC cycle time, counter checks) and transmit scheduling.

Time is always passed in (seconds, any monotonic origin); nothing here reads a clock. Inside, time is counted in
integers: the schedule in whole milliseconds (the DBC's cycle times are whole ms; :meth:`TxScheduler.due_ms`
takes a time in ms, as a lock-step tick gives it), the receive deadlines in whole nanoseconds (:func:`to_ns`, at
the edge where a time comes in as seconds).
"""

from __future__ import annotations

import logging
from collections import Counter as Tally
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

import can

from ..common.units import CV
from .codec import Codec, DecodedFrame, FrameError
from .e2e import MAX_DELTA
from .frame import data_frame

__all__ = ["DUPLICATE", "IGNORED", "NEW", "NS_PER_MS", "NS_PER_S", "REJECTED", "TIMEOUT_CYCLES", "RxMonitor", "RxState",
           "TxScheduler", "all_valid", "to_ns"]

log = logging.getLogger(__name__)

TIMEOUT_CYCLES = 3.0
DECODED_KEPT = 256  # RxMonitor: frames kept decoded per message (a steady plant repeats its frames, counter and all)
NS_PER_MS, NS_PER_S = 1_000_000, 1_000_000_000


def to_ns(t: float) -> int:
    """A time in seconds as whole nanoseconds (the nearest): where a float time comes in."""
    return round(t * NS_PER_S)

NEW, DUPLICATE, REJECTED, IGNORED = "new", "duplicate", "rejected", "ignored"


@dataclass(slots=True)
class RxState:
    """Validity of one received message: fresh within ``TIMEOUT_CYCLES`` cycle times, counter moving by the
    rules of :mod:`.e2e` (resynchronised by the first frame after a timeout) with its protection's modulus and
    largest step (``max_delta``, :mod:`.profiles`). ``counted`` False (a message without a counter): every frame
    that passes its checks is taken, none is a repeat or a duplicate."""

    name: str
    cycle_time: float
    counter_modulus: int = 16
    max_delta: int = MAX_DELTA
    counted: bool = True
    timeout: float | None = None  # [s]: the deadline if given (a binding's), else TIMEOUT_CYCLES cycle times
    # a multiplexed message: how many values a whole reading has (every page's signals and the multiplexer); a
    # frame's page updates its values, the other pages' keep theirs, and the message is received (fresh, valid)
    # from the frame that completes the first reading on. 0: not multiplexed (each frame holds every value)
    complete: int = 0
    last_time: float | None = None
    last_counter: int | None = None
    values: dict[str, float] = field(default_factory=dict)
    received: int = 0
    counter_jumps: int = 0  # gaps in the counter (it advanced by more than one)
    lost: int = 0  # frames missing in those gaps (at most max_delta - 1 each; a longer outage is a timeout)
    duplicates: int = 0  # byte-identical repeats of the last frame taken (retransmissions), ignored
    rejected: Tally[str] = field(default_factory=Tally)  # by cause: dlc, crc, data_id, range, malformed, counter
    last_data: bytes | None = None
    deadline: float = field(init=False)  # TIMEOUT_CYCLES cycle times [s]
    deadline_ns: int = field(init=False)  # the same in whole ns

    def __post_init__(self) -> None:
        self.deadline = TIMEOUT_CYCLES * self.cycle_time if self.timeout is None else self.timeout
        self.deadline_ns = to_ns(self.deadline)

    def update(self, now: float, frame: DecodedFrame, data: bytes = b"") -> str | None:
        """Take a decoded frame; returns why it was not taken (repeated or out-of-order counter), else None."""
        counter, last_counter = frame.counter, self.last_counter
        if last_counter is not None:
            step = (counter - last_counter) % self.counter_modulus
            if step == 0:  # also after a timeout: a sender whose counter froze never resynchronises
                return f"counter {counter} repeated"
            if step != 1:  # the usual step needs no further check
                resync = self.last_time is not None and not self.valid(now)  # timed out: any other step is taken
                if step > self.max_delta and not resync:
                    return f"counter {counter} after {last_counter}: out of order (step {step})"
                if not resync:
                    self.counter_jumps += 1
                    self.lost += step - 1
        if self.counted:
            self.last_counter = counter
            self.last_data = data
        if self.complete:  # (a new dict: decoded frames are shared, only read)
            self.values = {**self.values, **frame.values}
            if len(self.values) < self.complete:
                return None  # (its counter taken; the message not received until its every page has come)
        else:
            self.values = frame.values
        self.last_time = now
        self.received += 1
        return None

    def forget(self) -> None:
        """Check the next frame's counter against nothing (the sender restarts its counter)."""
        self.last_counter = self.last_data = None

    def valid(self, now: float) -> bool:
        """Whether the last frame taken is at most ``deadline`` old at ``now`` (both times counted in whole ns, as
        :func:`to_ns`, written out: it runs several times every control period)."""
        last = self.last_time
        return last is not None and round(now * NS_PER_S) - round(last * NS_PER_S) <= self.deadline_ns


def all_valid(states: Iterable[RxState], now: float) -> bool:
    """Whether every one of ``states`` is :meth:`RxState.valid` at ``now`` (``now`` taken to whole ns once)."""
    now_ns = round(now * NS_PER_S)
    for state in states:
        last = state.last_time
        if last is None or now_ns - round(last * NS_PER_S) > state.deadline_ns:
            return False
    return True


class RxMonitor:
    """Decodes and checks incoming frames for the messages a node reads; counts and logs what it rejects. A frame's
    bytes seen again (up to :data:`DECODED_KEPT` per message) give the frame decoded the first time: decoding is
    a pure function of the bytes, and the decoded frames are only read."""

    def __init__(self, codec: Codec, names: list[str]) -> None:
        self.codec = codec
        self.states = {}
        for name in names:
            protection = codec.protection(name)
            modulus = protection.counter_modulus
            self.states[name] = RxState(name, codec.cycle_time(name), modulus or 1, protection.max_delta, modulus > 0,
                                        codec.timeout(name), codec.complete_values(name))
        self._ids = {codec.frame_id(name): name for name in names}
        self._by_id: dict[int, tuple[RxState, Callable[[bytes], DecodedFrame], dict[bytes, DecodedFrame]]] = {
            frame_id: (self.states[name], codec.decoder(frame_id), {})  # take: one look-up per frame
            for frame_id, name in self._ids.items()}
        self._fd = codec.fd  # the CAN FD messages' frame IDs (their frames CAN FD, the others' classic)
        self.rejected: Tally[str] = Tally()
        self.received = 0
        self._checks: dict[int, tuple[str, Callable[[DecodedFrame], str | None]]] = {}

    def require(self, name: str, cause: str, check: Callable[[DecodedFrame], str | None]) -> None:
        """A further check on frames of ``name``, made after the end-to-end ones and before the frame is taken:
        ``check(frame)`` returns why it fails, or None; a failing frame is rejected for ``cause``, its counter
        not taken (e.g. a lock-step command whose SyncEcho answers no tick)."""
        self._checks[self.codec.frame_id(name)] = (cause, check)

    def wants(self, msg: can.Message) -> bool:
        return not msg.is_extended_id and msg.arbitration_id in self._ids

    def _state_of(self, msg: can.Message) -> RxState | None:
        """The state of the message ``msg`` is a frame of, if it is one this node reads (as :meth:`wants`)."""
        known = None if msg.is_extended_id else self._by_id.get(msg.arbitration_id)
        return None if known is None else known[0]

    def receive(self, msg: can.Message, now: float) -> DecodedFrame | None:
        """Take one frame. Returns the decoded frame if accepted, None if it is not ours, a duplicate or
        rejected."""
        status, frame = self.take(msg, now)
        return frame if status == NEW else None

    def take(self, msg: can.Message, now: float) -> tuple[str, DecodedFrame | None]:
        """Take one frame: (``NEW``, frame) if accepted; (``DUPLICATE``, frame) for a byte-identical repeat of
        the last frame taken of its message (a retransmission: counted, not taken, not an error); (``REJECTED``,
        None) when it fails its checks; (``IGNORED``, None) when it is not ours."""
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            return IGNORED, None
        if msg.is_fd != (msg.arbitration_id in self._fd):  # a frame of the other format than its message's
            frame_id = msg.arbitration_id
            if frame_id not in self._by_id:
                return IGNORED, None
            self.received += 1
            self._reject(self._by_id[frame_id][0], "dlc", f"0x{frame_id:03X}: "
                         + ("CAN FD frame of a classic CAN message" if msg.is_fd else
                            "classic CAN frame of a CAN FD message"))
            return REJECTED, None
        return self.take_data(msg.arbitration_id, bytes(msg.data), now)

    def take_data(self, frame_id: int, data: bytes | bytearray, now: float) -> tuple[str, DecodedFrame | None]:
        """:meth:`take` of a classic data frame with an 11-bit ID, given by its ID and data (a bytearray, as
        python-can's ``Message.data``, taken as its bytes)."""
        known = self._by_id.get(frame_id)
        if known is None:
            return IGNORED, None
        if not isinstance(data, bytes):
            data = bytes(data)
        state, decode, memo = known
        self.received += 1
        frame = memo.get(data)
        if frame is None:
            try:
                frame = decode(data)
            except FrameError as exc:
                self._reject(state, exc.reason, str(exc))
                return REJECTED, None
            if len(memo) >= DECODED_KEPT:
                memo.clear()
            memo[data] = frame
        if data == state.last_data:
            state.duplicates += 1
            return DUPLICATE, frame
        if self._checks and (extra := self._checks.get(frame_id)) is not None \
                and (failed := extra[1](frame)) is not None:
            self._reject(state, extra[0], f"{frame.name}: {failed}")
            return REJECTED, None
        last_counter = state.last_counter
        if last_counter is not None and (frame.counter - last_counter) % state.counter_modulus == 1 \
                and not state.complete:
            state.last_counter, state.last_data, state.last_time = frame.counter, data, now  # update's usual step,
            state.values = frame.values  # written out (every frame)
            state.received += 1
            return NEW, frame
        refused = state.update(now, frame, data)
        if refused is not None:
            self._reject(state, "counter", f"{frame.name}: {refused}")
            return REJECTED, None
        return NEW, frame

    def prime(self, msg: can.Message) -> None:
        """Make ``msg`` the last frame seen of its message without taking its values (a frame the other side
        already sent, e.g. the answer to the lockstep presence probe): its repeats are then duplicates and the
        next frame's counter is checked against it."""
        state = self.states[self._ids[msg.arbitration_id]]
        if not state.counted:
            return
        state.last_counter = self.codec.decode(msg.arbitration_id, bytes(msg.data)).counter
        state.last_data = bytes(msg.data)

    def _reject(self, state: RxState, reason: str, text: str) -> None:
        state.rejected[reason] += 1
        self.rejected[reason] += 1
        n = self.rejected[reason]
        if n <= 5 or n % 1000 == 0:  # log the first few and then every thousandth
            log.warning("rejected frame (%s, %d so far): %s", reason, n, text)

    def valid(self, name: str, now: float) -> bool:
        return self.states[name].valid(now)

    def values(self, name: str) -> dict[str, float]:
        return self.states[name].values

    @property
    def rejected_total(self) -> int:
        return sum(self.rejected.values())

    def counts(self) -> dict[str, dict]:
        """Per message: frames received (all, including rejected and duplicates), taken, rejected by cause,
        lost (counter gaps) and duplicates."""
        return {name: {"received": s.received + s.duplicates + sum(s.rejected.values()), "taken": s.received,
                       "rejected": dict(sorted(s.rejected.items())), "lost": s.lost, "duplicates": s.duplicates}
                for name, s in self.states.items()}


class TxScheduler:
    """Absolute-deadline transmit schedule: each message due every DBC cycle time from ``start``, counted in whole
    milliseconds (``next_due_ms``)."""

    def __init__(self, codec: Codec, names: list[str], start: float = 0.0) -> None:
        self.codec = codec
        start_ms = to_ns(start) // NS_PER_MS
        self.next_due_ms = {name: start_ms for name in names}
        self.counters = {name: 0 for name in names}
        self.sent = 0
        self._periods_ms = {name: codec.cycle_time_ms(name) for name in names}
        self.ids = {name: codec.frame_id(name) for name in names}
        self._moduli = {name: codec.protection(name).counter_modulus or 1 for name in names}  # 1: no counter
        self._encoders = {name: codec.encoder(name) for name in names}  # frame: one per frame
        self._fixed = {name: (self._periods_ms[name], self._moduli[name], self.ids[name]) for name in names}

    @property
    def next_due(self) -> dict[str, float]:
        """The next deadlines in seconds."""
        return {name: due / CV.S_TO_MS for name, due in self.next_due_ms.items()}

    def due(self, now: float) -> list[str]:
        """:meth:`due_ms` at ``now`` [s], a float time (a clock's, or a caller's, e.g. a stamp tick x cycle time a few
        ulp off its decimal) taken to the nearest whole ns: a message due at d ms is due from d ms on."""
        return self.due_ms(to_ns(now) // NS_PER_MS)

    def due_ms(self, now_ms: int) -> list[str]:
        """Messages due at ``now_ms`` [ms], in DBC order; their next deadlines advance by whole cycle times (a late
        message is sent once and keeps its grid)."""
        names = []
        next_due, periods = self.next_due_ms, self._periods_ms
        for name, due in next_due.items():
            if now_ms >= due:
                names.append(name)
                period = periods[name]
                next_due[name] = due + ((now_ms - due) // period + 1) * period
        return names

    def encode_due_ms(self, now_ms: int, encoders: Mapping[str, Callable[..., bytes]],
                      *args: object) -> list[tuple[int, bytes]]:
        """The frames due at ``now_ms`` (:meth:`due_ms`) as (ID, data), in DBC order, each encoded by
        ``encoders[name](*args, counter)`` with its next counter (:meth:`next_counter`): the two, fused (a sender
        that encodes its own state every cycle)."""
        frames = []
        next_due, counters, fixed = self.next_due_ms, self.counters, self._fixed
        for name, due in next_due.items():
            if now_ms >= due:
                period, modulus, frame_id = fixed[name]
                next_due[name] = due + ((now_ms - due) // period + 1) * period
                counter = counters[name]
                counters[name] = (counter + 1) % modulus
                frames.append((frame_id, encoders[name](*args, counter)))
        self.sent += len(frames)
        return frames

    def frame(self, name: str, values: dict[str, float], timestamp: float = 0.0) -> can.Message:
        """The next frame of ``name`` (counter advanced)."""
        return data_frame(self.ids[name], self.data(name, values), timestamp, fd=self.codec.fd)

    def next_counter(self, name: str) -> int:
        """The counter of the next frame of ``name`` (advanced, the frame counted as sent), for a sender that
        encodes the frame itself (e.g. with a fused encoder, :meth:`Codec.fused_encoder`)."""
        counters = self.counters
        counter = counters[name]
        counters[name] = (counter + 1) % self._moduli[name]
        self.sent += 1
        return counter

    def data(self, name: str, values: Mapping[str, float]) -> bytes:
        """The data of the next frame of ``name`` (counter advanced), whose ID is ``ids[name]``."""
        counters = self.counters
        counter = counters[name]
        counters[name] = (counter + 1) % self._moduli[name]
        self.sent += 1
        return self._encoders[name](values, counter)
