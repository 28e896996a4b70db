"""Fault injection between a node and its bus.

:class:`FaultInjector` is the pure part: ``apply(msg, t)`` turns one frame a node sends at time ``t`` into the
frames that reach the bus now (none, one changed, two ...), ``release(t)`` gives back delayed frames that are due.
Signal faults decode the frame with the DBC, change the value and re-encode it with a valid counter and CRC, so
they test plausibility, not protection. The protection faults (``corrupt_crc``, ``freeze_counter``) act on the
message's protection, whatever its profile (:mod:`..profiles`): the CRC field's bits inverted; the counter held,
the CRC sealed again. A message's protection is the one given (a node's codec's, :meth:`.Codec.protections`), else
the one the database gives it (an ARXML's E2E data, else the dsg-hil scheme on Counter/CRC signals, else none).
Draws are from a seeded generator: in lockstep the same faults hit the same frames on every run.

:class:`FaultyBus` wraps a python-can bus with an injector on what the node sends, so it works for the plant's
frames, the TCU's, or, between two buses (:func:`bridge_step`), a real ECU's.
"""

from __future__ import annotations

import logging
import random
import time
from collections import Counter as Tally
from collections.abc import Callable, Iterable, Mapping
from typing import cast

import can
from cantools.database.can import Database, Message, Signal
from cantools.database.errors import EncodeError

from ..codec import raw_range, signal_range
from ..e2e import ProtectionError
from ..profiles import FrameProtection, Unprotected, protection_for
from .spec import FaultError, FaultSpec, check_against_dbc

__all__ = ["FaultInjector", "FaultyBus", "bridge_step", "outside_range"]

log = logging.getLogger(__name__)


def outside_range(signal: Signal) -> float:
    """A value the signal's bits can carry that lies just outside its DBC range [minimum, maximum]."""
    bottom, top = raw_range(signal)
    minimum, maximum = signal_range(signal)
    step = abs(signal.scale)
    if top > maximum + step / 2:
        return min(maximum + step, top)
    if bottom < minimum - step / 2:
        return max(minimum - step, bottom)
    raise FaultError(f"{signal.name}: its {signal.length} bits cannot carry a value outside [{minimum:g}, "
                     f"{maximum:g}]")


class FaultInjector:
    """Applies ``specs`` to the frames of one sender. ``counts[spec.describe()]`` counts the frames each hit.
    ``protections``: the messages' protections by name (those not given: as the database gives them)."""

    def __init__(self, db: Database, specs: Iterable[FaultSpec], seed: int = 0,
                 protections: Mapping[str, FrameProtection] | None = None) -> None:
        self.specs = tuple(specs)
        for spec in self.specs:
            check_against_dbc(spec, db, spec.origin)
        self._messages = {m.frame_id: m for m in db.messages}
        self._protections: dict[int, FrameProtection] = {}
        self._by_id: dict[int, list[int]] = {}
        for i, spec in enumerate(self.specs):
            if spec.kind == "flood":
                continue
            assert spec.message is not None  # check_against_dbc: every other kind names its message
            if spec.kind == "out_of_range":  # fail at start-up, not mid-run, if the bits cannot carry it
                try:
                    outside_range(db.get_message_by_name(spec.message).get_signal_by_name(str(spec.signal)))
                except FaultError as exc:
                    raise FaultError(f"{spec.origin}: {exc}") from None
            message = db.get_message_by_name(spec.message)
            protection = self._protections.setdefault(message.frame_id, _protection(message, protections))
            needs = {"corrupt_crc": "crc", "freeze_counter": "counter"}.get(spec.kind)
            if needs is not None and needs not in {name for name, _, _ in protection.layout}:
                raise FaultError(f"{spec.origin}: {spec.message} has no {needs.upper() if needs == 'crc' else needs} "
                                 f"to fault (protection {protection.profile})")
            self._by_id.setdefault(message.frame_id, []).append(i)
        self._rng = random.Random(seed)
        self._frozen: dict[int, int] = {}
        self._held: list[tuple[float, int, can.Message]] = []
        self._sequence = 0
        self.counts: Tally[str] = Tally()
        self.encode_errors: Tally[str] = Tally()  # frames a fault could not encode: sent unchanged

    # ---- the frames a node sends -----------------------------------------------------------------------------
    def apply(self, msg: can.Message, t: float) -> list[can.Message]:
        """The frames that go on the bus at ``t`` for ``msg`` (in order)."""
        out = [msg]
        for i in self._by_id.get(msg.arbitration_id, ()):
            spec = self.specs[i]
            if not spec.active(t) or not out or not self._hit(spec):
                if i in self._frozen and not spec.active(t):
                    del self._frozen[i]
                continue
            self.counts[spec.describe()] += 1
            out = [changed for frame in out for changed in self._change(i, spec, frame, t)]
        for spec in self.specs:
            if spec.kind == "flood" and spec.active(t) and self._hit(spec):
                self.counts[spec.describe()] += spec.rate
                out += [can.Message(arbitration_id=spec.frame_id, is_extended_id=False, timestamp=msg.timestamp,
                                    data=bytes(self._rng.getrandbits(8) for _ in range(8))) for _ in range(spec.rate)]
        return out

    def release(self, t: float) -> list[can.Message]:
        """Delayed frames whose time has come, oldest first."""
        due = [entry for entry in self._held if entry[0] <= t]
        if due:
            self._held = [entry for entry in self._held if entry[0] > t]
        return [msg for _, _, msg in sorted(due, key=lambda e: (e[0], e[1]))]

    @property
    def injected(self) -> int:
        return sum(self.counts.values())

    def hits(self) -> str:
        """One line for the user: each specification and the frames it hit (and those it could not encode)."""
        return ", ".join(f"{s.describe()} {self.counts[s.describe()]}{self._unencoded(s)}" for s in self.specs) \
            or "none"

    def _unencoded(self, spec: FaultSpec) -> str:
        n = self.encode_errors[spec.describe()]
        return f" ({n} not encodable: sent unchanged)" if n else ""

    # ---- one fault on one frame ---------------------------------------------------------------------------------
    def _hit(self, spec: FaultSpec) -> bool:
        return spec.probability >= 1.0 or self._rng.random() < spec.probability

    def _change(self, i: int, spec: FaultSpec, msg: can.Message, t: float) -> list[can.Message]:
        kind = spec.kind
        if kind == "drop":
            return []
        if kind == "duplicate":
            return [msg, _copy(msg, bytes(msg.data))]
        if kind == "delay":
            self._sequence += 1
            self._held.append((t + spec.delay_s, self._sequence, msg))
            return []
        protection = self._protections[msg.arbitration_id]
        if kind == "corrupt_crc":
            _, offset, bits = next(f for f in protection.layout if f[0] == "crc")
            whole = int.from_bytes(msg.data, "little") ^ ((1 << bits) - 1) << offset
            return [_copy(msg, whole.to_bytes(len(msg.data), "little"))]
        if kind == "wrong_dlc":
            data = bytes(msg.data)[:spec.dlc].ljust(spec.dlc, b"\x00")
            return [_copy(msg, data)]
        data = bytes(msg.data)
        message = self._messages[msg.arbitration_id]
        if kind == "freeze_counter":  # (a CAN FD frame's padding not sealed)
            counter = self._frozen.setdefault(i, protection.counter(data))
            return [_copy(msg, protection.seal(data[:message.length], counter) + data[message.length:])]
        values = _decode(message, data[:message.length], scaling=True)  # (a CAN FD frame's padding apart)
        if spec.signal is None:  # parse_fault gives every other kind its MESSAGE.Signal
            raise FaultError(f"{spec.origin}: {kind} needs a target MESSAGE.Signal")
        elif kind == "stuck":
            values[spec.signal] = spec.value
        elif kind == "offset":
            values[spec.signal] = float(values[spec.signal]) + spec.value
        elif kind == "gain":
            values[spec.signal] = float(values[spec.signal]) * spec.value
        elif kind == "out_of_range":
            values[spec.signal] = outside_range(message.get_signal_by_name(spec.signal))
        try:
            return [_copy(msg, protection.seal(message.encode(values, scaling=True, strict=False),
                                               protection.counter(data)) + data[message.length:])]
            # (no range check: a fault may leave it)
        except (OverflowError, ValueError, EncodeError) as exc:  # e.g. an offset or gain pushing the value off the bits
            if not self.encode_errors[spec.describe()]:
                log.warning("%s at t=%.3f s: %s cannot be encoded (%s): such frames are sent unchanged, counted",
                            spec.origin, t, spec.target, exc)
            self.encode_errors[spec.describe()] += 1
            return [msg]


def _decode(message: Message, data: bytes, scaling: bool) -> dict[str, float]:
    """The raw (or scaled) signal values; a dict, as the DBC has no container messages."""
    return cast("dict[str, float]", message.decode(data, decode_choices=False, scaling=scaling))


def _protection(message: Message, given: Mapping[str, FrameProtection] | None) -> FrameProtection:
    """``message``'s protection: as ``given``, else as the database gives it, else none."""
    if given is not None and message.name in given:
        return given[message.name]
    try:
        return protection_for(message)
    except ProtectionError:
        return Unprotected(message.length)


def _copy(msg: can.Message, data: bytes) -> can.Message:
    return can.Message(arbitration_id=msg.arbitration_id, is_extended_id=msg.is_extended_id, data=data,
                       dlc=len(data), timestamp=msg.timestamp, channel=msg.channel, is_rx=False, is_fd=msg.is_fd,
                       bitrate_switch=msg.bitrate_switch)


class FaultyBus(can.BusABC):
    """A python-can bus that sends through a :class:`FaultInjector`; receiving is untouched.

    ``clock()`` gives the sender's time for the fault windows (simulated time in lockstep)."""

    def __init__(self, inner: can.BusABC, injector: FaultInjector,
                 clock: Callable[[], float] | None = None) -> None:
        self.inner, self.injector = inner, injector
        if clock is None:
            start = time.monotonic()
            clock = lambda: time.monotonic() - start  # noqa: E731
        self.clock = clock
        self.channel_info = f"faults on {inner.channel_info}"
        super().__init__(channel=getattr(inner, "channel", ""))  # BusABC only requires it

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        now = self.clock()
        for frame in (*self.injector.release(now), *self.injector.apply(msg, now)):
            self.inner.send(frame, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        for frame in self.injector.release(self.clock()):
            self.inner.send(frame)
        return self.inner.recv(timeout), False

    def shutdown(self) -> None:
        super().shutdown()
        self.inner.shutdown()


def bridge_step(source: can.BusABC, sink: can.BusABC, injector: FaultInjector, t: float,
                timeout: float = 0.0) -> int:
    """Forward the frames waiting on ``source`` to ``sink`` through ``injector`` (e.g. a real ECU on can0 and
    the plant on vcan0); returns how many frames went out."""
    sent = 0
    for frame in injector.release(t):
        sink.send(frame)
        sent += 1
    while (msg := source.recv(timeout)) is not None:
        for frame in injector.apply(msg, t):
            sink.send(frame)
            sent += 1
        timeout = 0.0
    return sent
