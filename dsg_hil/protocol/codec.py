"""DBC codec with the frame protection of this contract (:mod:`.e2e`): the ``Counter`` and ``CRC`` signals are
filled here, never by callers, at the positions the DBC gives them.

Every message and signal the code uses is resolved once, at start-up: a missing one raises :class:`ProtocolError`
naming it. Encoding clamps each value to its signal's DBC range, then encodes with ``strict=True``; decoding
rejects (never clamps) a frame with a wrong DLC, CRC or a value outside its range.

The frames are encoded and decoded by functions generated per message from the DBC (:mod:`.generated`), which
do byte for byte what the cantools path here does, five times faster; ``reference=True`` keeps the cantools path
for every message (the reference of the tests, the baseline of ``bench/closed_loop_speed.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from importlib import resources
from pathlib import Path
from typing import NamedTuple, cast

import cantools
from cantools.database.can import Database, Message

from .e2e import COUNTER, CRC, Protection, ProtectionError
from ..common.errors import InputError
from ..common.units import CV
from .generated import dict_of, generate, generate_fused, generate_planned, plan, unsupported
from .plan import COMPILED as PLANS_COMPILED, MessagePlan
from .ranges import raw_range, signal_range  # noqa: F401 - raw_range: re-exported (the fault injector)

__all__ = ["Codec", "DEFAULT_DBC", "DecodedFrame", "FrameError", "ProtocolError", "load_dbc"]

DEFAULT_DBC = resources.files("dsg_hil") / "data" / "dsg_hil.dbc"  # the package's copy of dbc/dsg_hil.dbc


class ProtocolError(InputError):
    """The DBC is missing, unreadable, or lacks a message or signal the code needs."""


class FrameError(InputError):
    """A received frame is not acceptable. ``reason`` is one of: unknown, dlc, crc, range, malformed."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


class DecodedFrame(NamedTuple):
    """A frame that passed its checks: its message, signal values (Counter and CRC apart) and counter. A named
    tuple: built for every frame received, at a fraction of a frozen dataclass's cost."""

    name: str
    values: dict[str, float]
    counter: int


def load_dbc(path: str | Path | None = None) -> Database:
    """Load a DBC file strictly; ``None``: the one shipped inside the package (read as a package resource)."""
    try:
        if path is None:
            db = cantools.database.load_string(DEFAULT_DBC.read_text(encoding="utf-8"), "dbc", strict=True)
        else:
            db = cantools.database.load_file(str(path), strict=True)
    except FileNotFoundError:
        raise ProtocolError(f"{path or DEFAULT_DBC}: DBC file not found") from None
    except Exception as exc:  # cantools raises several types for a bad file
        raise ProtocolError(f"{path or DEFAULT_DBC}: cannot load DBC ({exc})") from None
    if not isinstance(db, Database):  # a .cdd/.odx file is a diagnostics database
        raise ProtocolError(f"{path or DEFAULT_DBC}: not a CAN database")
    return db


class Codec:
    """Encode and decode the messages named in ``uses`` ({message: [signals the code reads or writes]}).

    ``reference``: encode and decode through cantools only (no generated functions). ``plans``: decode, and encode
    from expressions (:meth:`expression_encoder`), by the messages' plans (:mod:`.plan`), which give the same frames
    and values; by default where the plans run compiled (the mypyc build, :data:`.plan.COMPILED`), faster there
    than the generated source, slower run by the interpreter."""

    def __init__(self, db: Database, uses: Mapping[str, Sequence[str]], *, reference: bool = False,
                 plans: bool | None = None) -> None:
        self.db = db
        self.reference = reference
        self._plans: dict[str, MessagePlan] = {}
        use_plans = PLANS_COMPILED if plans is None else plans
        self._by_name: dict[str, Message] = {}
        self._by_id: dict[int, Message] = {}
        self._protection: dict[int, Protection] = {}
        self._encoders: dict[str, Callable[[Mapping[str, float], int], bytes]] = {}
        self._decoders: dict[int, Callable[[bytes], DecodedFrame]] = {}
        self.sources: dict[str, str] = {}  # the generated functions' source, by message
        for name, signals in uses.items():
            try:
                message = db.get_message_by_name(name)
            except KeyError:
                raise ProtocolError(f"message {name} is not in the DBC") from None
            for signal in (*signals, COUNTER, CRC):
                try:
                    message.get_signal_by_name(signal)
                except KeyError:
                    raise ProtocolError(f"signal {name}.{signal} is not in the DBC") from None
            if message.cycle_time is None or message.cycle_time <= 0:
                raise ProtocolError(f"message {name} has no GenMsgCycleTime in the DBC")
            try:
                self._protection[message.frame_id] = Protection.of(message)
            except ProtectionError as exc:
                raise ProtocolError(str(exc)) from None
            self._by_name[name] = message
            self._by_id[message.frame_id] = message
            self._encoders[name] = partial(self._encode_reference, name)
            self._decoders[message.frame_id] = partial(self._decode_reference, message)
            protection = self._protection[message.frame_id]
            if not reference and unsupported(message, protection) is None:
                generated = generate(message, protection, FrameError, DecodedFrame)
                self._encoders[name], self._decoders[message.frame_id] = generated.encode, generated.decode
                self.sources[name] = generated.source
                message_plan = plan(message, protection, FrameError, DecodedFrame) if use_plans else None
                if message_plan is not None:
                    self._plans[name] = message_plan
                    self._decoders[message.frame_id] = message_plan.decode

    # ---- lookup --------------------------------------------------------------------------------------------
    def message(self, name: str) -> Message:
        return self._by_name[name]

    def frame_id(self, name: str) -> int:
        return self._by_name[name].frame_id

    def protection(self, name: str) -> Protection:
        """Where ``name`` carries its counter and CRC."""
        return self._protection[self._by_name[name].frame_id]

    def cycle_time(self, name: str) -> float:
        """The message's GenMsgCycleTime [s]."""
        return self.cycle_time_ms(name) / CV.S_TO_MS

    def cycle_time_ms(self, name: str) -> int:
        """The message's GenMsgCycleTime [ms], a whole number (for schedules counted in integers)."""
        return cast(int, self._by_name[name].cycle_time)  # checked in __init__

    # ---- encode / decode -------------------------------------------------------------------------------------
    def encode(self, name: str, values: Mapping[str, float], counter: int) -> bytes:
        """Frame data for ``name``: values clamped to their DBC ranges (NaN -> the signal's initial value or
        its minimum), counter and CRC filled in. Signals not given take their DBC initial value (or 0)."""
        return self._encoders[name](values, counter)

    def encoder(self, name: str) -> Callable[[Mapping[str, float], int], bytes]:
        """:meth:`encode` of ``name`` as one callable ``(values, counter) -> data``, for a sender of it each cycle."""
        return self._encoders[name]

    def expression_encoder(self, name: str, args: Sequence[str], values: Mapping[str, str],
                           namespace: Mapping[str, object] | None = None, *,
                           floats: bool = False) -> Callable[..., bytes]:
        """An encoder of ``name`` as ``f(*args, counter)`` whose signal values are the Python expressions ``values``
        of those arguments (by signal; ``namespace``: other names they use; a signal not named takes its default):
        :meth:`encode` of ``{signal: expression}``, byte for byte. Fused where the codec generated the message's
        functions (:func:`.generated.generate_fused`: no dict built and looked up, for a sender that encodes its
        own state every cycle); else the dict, then :meth:`encoder`. ``floats``: every expression gives a float
        (no ``float()`` of it taken again)."""
        message = self._by_name[name]
        if name in self._plans:
            return generate_planned(message, self._plans[name], args, values, namespace, floats=floats)[0]
        if name in self.sources:
            return generate_fused(message, self._protection[message.frame_id], args, values, namespace,
                                  floats=floats)[0]
        encode, of = self._encoders[name], dict_of(args, values, namespace)
        return lambda *a: encode(of(*a[:-1]), a[-1])

    def decoder(self, frame_id: int) -> Callable[[bytes], DecodedFrame]:
        """:meth:`decode` of a frame id the codec knows as one callable ``data -> frame`` (KeyError if unknown)."""
        return self._decoders[frame_id]

    def decode(self, frame_id: int, data: bytes) -> DecodedFrame:
        """Check DLC, CRC and ranges, then decode. Raises :class:`FrameError` with a reason."""
        decoder = self._decoders.get(frame_id)
        if decoder is None:
            raise FrameError("unknown", f"frame 0x{frame_id:03X} is not one this node reads")
        return decoder(data)

    # ---- the cantools path (the reference) -----------------------------------------------------------------------
    def _encode_reference(self, name: str, values: Mapping[str, float], counter: int) -> bytes:
        message = self._by_name[name]
        data: dict[str, float] = {}
        for signal in message.signals:
            if signal.name in (COUNTER, CRC):
                continue
            value = values.get(signal.name)
            lo, hi = signal_range(signal)
            default = min(max(0.0, lo), hi) if signal.raw_initial is None else \
                signal.raw_initial * signal.scale + signal.offset  # .initial may be a value name (VAL_)
            if value is None or not math.isfinite(value):
                value = default
            data[signal.name] = min(max(float(value), lo), hi)
        protection = self._protection[message.frame_id]
        data[COUNTER] = counter % protection.counter_modulus
        data[CRC] = 0
        return protection.seal(message.encode(data, strict=True, scaling=True))

    def _decode_reference(self, message: Message, data: bytes) -> DecodedFrame:
        frame_id = message.frame_id
        if len(data) != message.length:
            raise FrameError("dlc", f"{message.name}: DLC {len(data)}, expected {message.length}")
        if not self._protection[frame_id].check(data):
            raise FrameError("crc", f"{message.name}: CRC mismatch")
        try:
            values = cast("dict[str, float]",  # no container messages in the DBC: a dict
                          message.decode(bytes(data), decode_choices=False, scaling=True))
        except Exception as exc:  # noqa: BLE001 - cantools raises several types
            raise FrameError("malformed", f"{message.name}: {exc}") from None
        for signal in message.signals:
            v = values[signal.name]
            lo, hi = signal_range(signal)
            if not (lo - 1e-9 <= v <= hi + 1e-9):
                raise FrameError("range", f"{message.name}.{signal.name} = {v} outside [{lo:g}, {hi:g}]")
        counter = int(values.pop(COUNTER))
        values.pop(CRC)
        return DecodedFrame(message.name, {k: float(v) for k, v in values.items()}, counter)
