"""DBC codec with each message's end-to-end protection (:mod:`.profiles`): by default this contract's own scheme
(:mod:`.e2e`), its ``Counter`` and ``CRC`` signals filled here, never by callers, at the positions the DBC gives
them; per message an AUTOSAR E2E profile or none where ``protection`` says so (or an ARXML's E2E data does). The
signals that carry a protection are not values: encoding ignores them, decoding returns none of them.

Every message and signal the code uses is resolved once, at start-up: a missing one raises :class:`ProtocolError`
naming it. Encoding clamps each value to its signal's DBC range, then encodes with ``strict=True``; decoding
rejects (never clamps) a frame with a wrong DLC, CRC or a value outside its range.

A message the database says is CAN FD (cantools' ``Message.is_fd``, from the DBC's ``VFrameFormat``) is sent as a
CAN FD frame (:attr:`Codec.fd`: its frame ID and its bit-rate switch, the DBC's ``CANFD_BRS``) of up to 64 bytes;
a length that no DLC codes (e.g. 10) travels in the next frame length that one does (12), padded with zeros, the
padding checked for length only on receive.

The frames are encoded and decoded by functions generated per message from the DBC (:mod:`.generated`), which
do byte for byte what the cantools path here does, five times faster; ``reference=True`` keeps the cantools path
for every message (the reference of the tests, the baseline of ``bench/closed_loop_speed.py``). A message under
another profile than the dsg-hil scheme gets generated functions too, which call its protection's ``seal``,
``cause`` and ``counter``; no plan (:mod:`.plan` holds the dsg-hil scheme's CRC only).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple, cast

import cantools
from cantools.database.can import Database, Message

from .e2e import COUNTER, CRC, Protection, ProtectionError
from .frame import fd_length
from .profiles import CAUSE_TEXT, FrameProtection, ProtectionSpec, protection_for, protection_signals
from ..common.errors import InputError
from ..common.units import CV
from .generated import dict_of, generate, generate_fused, generate_planned, plan, unsupported
from .plan import COMPILED as PLANS_COMPILED, MessagePlan
from .ranges import raw_range, signal_range  # noqa: F401 - raw_range: re-exported (the fault injector)

__all__ = ["Codec", "DEFAULT_DBC", "DecodedFrame", "FrameError", "ProtocolError", "bitrate_switch", "frame_length",
           "load_dbc"]

DEFAULT_DBC = resources.files("dsg_hil") / "data" / "dsg_hil.dbc"  # the package's copy of dbc/dsg_hil.dbc


class ProtocolError(InputError):
    """The DBC is missing, unreadable, or lacks a message or signal the code needs."""


class FrameError(InputError):
    """A received frame is not acceptable. ``reason`` is one of: unknown, dlc, crc, data_id, counter, range,
    malformed."""

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


def bitrate_switch(message: Message, db: Database | None = None) -> bool:
    """Whether a CAN FD ``message`` switches to the data bit rate: the DBC's ``CANFD_BRS`` attribute of the message,
    else its default in ``db`` (the database's definition), else True (as Vector's tools default it)."""
    dbc = message.dbc
    value: object = None
    definition: Any = None
    if dbc is not None and "CANFD_BRS" in dbc.attributes:
        value = dbc.attributes["CANFD_BRS"].value
        definition = dbc.attributes["CANFD_BRS"].definition
    else:
        definition = db.dbc.attribute_definitions.get("CANFD_BRS") if db is not None and db.dbc is not None else None
        value = definition.default_value if definition is not None else None
    if value is None:
        return True
    choices = definition.choices if definition is not None else None
    if isinstance(value, int) and choices and 0 <= value < len(choices):  # an ENUM's index
        value = choices[value]
    return str(value).strip().strip('"') not in ("0", "", "false", "False")


def frame_length(message: Message) -> int:
    """The data length of ``message``'s frames: its length, snapped up to a CAN FD length for a CAN FD message;
    :class:`ProtocolError` for a classic message over 8 bytes or a CAN FD one over 64."""
    if not message.is_fd:
        if message.length > 8:
            raise ProtocolError(f"message {message.name}: {message.length} bytes on classic CAN (at most 8): a CAN FD "
                                f"message needs VFrameFormat CAN_FD in the DBC")
        return message.length
    if message.length > 64:
        raise ProtocolError(f"message {message.name}: {message.length} bytes (a CAN FD frame carries at most 64)")
    return fd_length(message.length)


class Codec:
    """Encode and decode the messages named in ``uses`` ({message: [signals the code reads or writes]}).

    ``reference``: encode and decode through cantools only (no generated functions). ``plans``: decode, and encode
    from expressions (:meth:`expression_encoder`), by the messages' plans (:mod:`.plan`), which give the same frames
    and values; by default where the plans run compiled (the mypyc build, :data:`.plan.COMPILED`), faster there
    than the generated source, slower run by the interpreter. ``protection``: a message's protection as a table
    or :class:`.profiles.ProtectionSpec` (e.g. ``{"TCU_CMD": {"profile": "P05", "data_id": 0x1234}}``); a message
    not named there has the ARXML's E2E data, if any, else the dsg-hil scheme on its Counter and CRC signals.
    ``timeouts``: receive timeouts [s] by message, where not the receiver's default (:meth:`timeout`)."""

    def __init__(self, db: Database, uses: Mapping[str, Sequence[str]], *, reference: bool = False,
                 plans: bool | None = None,
                 protection: Mapping[str, ProtectionSpec | Mapping[str, object]] | None = None,
                 timeouts: Mapping[str, float] | None = None) -> None:
        self.db = db
        self._timeouts = dict(timeouts or {})
        self.reference = reference
        self._plans: dict[str, MessagePlan] = {}
        self.fd: dict[int, bool] = {}  # the CAN FD messages used: by frame ID, their bit-rate switch
        self._multiplexer: dict[str, str] = {}  # multiplexed messages: their multiplexer signal
        self._pages: dict[str, list[int]] = {}  # ... and its values, the pages sent in turn
        self._pages_sent: dict[str, int] = {}  # ... and its frames encoded so far without a page given
        self._padding: dict[str, bytes] = {}  # CAN FD messages of a length no DLC codes: the zeros sent after them
        use_plans = PLANS_COMPILED if plans is None else plans
        self._by_name: dict[str, Message] = {}
        self._by_id: dict[int, Message] = {}
        self._protection: dict[int, FrameProtection] = {}
        self._carriers: dict[int, frozenset[str]] = {}  # by frame ID: the signals that carry the protection
        specs = dict(protection or {})
        unknown = sorted(set(specs) - set(uses))
        if unknown:
            raise ProtocolError(f"protection given for {unknown[0]}, a message the codec does not use")
        self._encoders: dict[str, Callable[[Mapping[str, float], int], bytes]] = {}
        self._decoders: dict[int, Callable[[bytes], DecodedFrame]] = {}
        self.sources: dict[str, str] = {}  # the generated functions' source, by message
        for name, signals in uses.items():
            try:
                message = db.get_message_by_name(name)
            except KeyError:
                raise ProtocolError(f"message {name} is not in the DBC") from None
            spec = specs.get(name)
            default = spec is None and (message.autosar is None or message.autosar.e2e is None)
            for signal in (*signals, *((COUNTER, CRC) if default else ())):
                try:
                    message.get_signal_by_name(signal)
                except KeyError:
                    raise ProtocolError(f"signal {name}.{signal} is not in the DBC") from None
            if message.cycle_time is None or message.cycle_time <= 0:
                raise ProtocolError(f"message {name} has no GenMsgCycleTime in the DBC")
            length = frame_length(message)
            if message.is_fd:
                self.fd[message.frame_id] = bitrate_switch(message, db)
            try:
                protected = protection_for(message, spec)
            except ProtectionError as exc:
                if not default:
                    raise
                raise ProtocolError(str(exc)) from None
            if message.is_multiplexed():
                self._multiplex(message)
            carriers = protection_signals(message, protected)
            if carriers & set(signals):
                raise ProtocolError(f"signal {name}.{sorted(carriers & set(signals))[0]} carries the message's "
                                    f"{protected.profile} protection: not a value")
            self._protection[message.frame_id], self._carriers[message.frame_id] = protected, carriers
            self._by_name[name] = message
            self._by_id[message.frame_id] = message
            self._encoders[name] = partial(self._encode_reference, name)
            self._decoders[message.frame_id] = partial(self._decode_reference, message)
            if not reference and unsupported(message, protected) is None:
                generated = generate(message, protected, FrameError, DecodedFrame)
                self._encoders[name], self._decoders[message.frame_id] = generated.encode, generated.decode
                self.sources[name] = generated.source
                message_plan = plan(message, protected, FrameError, DecodedFrame) \
                    if use_plans and isinstance(protected, Protection) else None  # (the dsg-hil scheme's only)
                if message_plan is not None:
                    self._plans[name] = message_plan
                    self._decoders[message.frame_id] = message_plan.decode
            if length != message.length:
                self._padding[name] = bytes(length - message.length)
                self._encoders[name] = partial(_padded, self._encoders[name], self._padding[name])
                self._decoders[message.frame_id] = partial(_unpadded, self._decoders[message.frame_id], message,
                                                           length)

    def _multiplex(self, message: Message) -> None:
        """Take a multiplexed message's pages: one multiplexer signal, its values those the signals name (a
        multiplexer inside a page, or none, is a :class:`ProtocolError`)."""
        multiplexers = [signal for signal in message.signals if signal.is_multiplexer]
        if len(multiplexers) != 1 or multiplexers[0].multiplexer_ids is not None:
            raise ProtocolError(f"message {message.name}: one multiplexer signal, itself not multiplexed, is "
                                f"supported, not {[s.name for s in multiplexers]}")
        self._multiplexer[message.name] = multiplexers[0].name
        self._pages[message.name] = sorted({page for signal in message.signals
                                            for page in signal.multiplexer_ids or ()})

    # ---- lookup --------------------------------------------------------------------------------------------
    def message(self, name: str) -> Message:
        return self._by_name[name]

    def frame_id(self, name: str) -> int:
        return self._by_name[name].frame_id

    def protection(self, name: str) -> FrameProtection:
        """How ``name`` is protected: its counter and CRC, where it carries them."""
        return self._protection[self._by_name[name].frame_id]

    def protections(self) -> dict[str, FrameProtection]:
        """Every message's protection, by name (e.g. for the fault injector of a node's frames)."""
        return {name: self._protection[message.frame_id] for name, message in self._by_name.items()}

    def complete_values(self, name: str) -> int:
        """A multiplexed message's number of values (every page's signals and the multiplexer, not the
        protection's), which its frames give a page at a time; 0 for any other message (each frame gives all)."""
        if name not in self._multiplexer:
            return 0
        message = self._by_name[name]
        return len({signal.name for signal in message.signals} - self._carriers[message.frame_id])

    def cycle_time(self, name: str) -> float:
        """The message's GenMsgCycleTime [s]."""
        return self.cycle_time_ms(name) / CV.S_TO_MS

    def timeout(self, name: str) -> float | None:
        """The receive timeout [s] given for ``name`` (``timeouts``: a binding's), else None (the receiver's
        default: :data:`.validity.TIMEOUT_CYCLES` cycle times)."""
        return self._timeouts.get(name)

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
        padding = self._padding.get(name)
        if name in self._plans:
            fused = generate_planned(message, self._plans[name], args, values, namespace, floats=floats)[0]
        elif name in self.sources:
            fused = generate_fused(message, self._protection[message.frame_id], args, values, namespace,
                                   floats=floats)[0]
        else:
            encode, of = self._encoders[name], dict_of(args, values, namespace)
            return lambda *a: encode(of(*a[:-1]), a[-1])
        return fused if padding is None else lambda *a: fused(*a) + padding

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
        protection, carriers = self._protection[message.frame_id], self._carriers[message.frame_id]
        data: dict[str, float] = {}
        page = self._page(message, values)
        for signal in message.signals:
            if page is not None and signal.multiplexer_ids is not None and page not in signal.multiplexer_ids:
                continue  # (another page's)
            lo, hi = signal_range(signal)
            if signal.name in carriers:  # filled by the protection's seal
                data[signal.name] = min(max(0.0, lo), hi)
                continue
            value = values.get(signal.name)
            default = min(max(0.0, lo), hi) if signal.raw_initial is None else \
                signal.raw_initial * signal.scale + signal.offset  # .initial may be a value name (VAL_)
            if value is None or not math.isfinite(value):
                value = default
            data[signal.name] = min(max(float(value), lo), hi)
        if page is not None:
            data[self._multiplexer[message.name]] = page
        return protection.seal(message.encode(data, strict=True, scaling=True), counter)

    def _page(self, message: Message, values: Mapping[str, float]) -> int | None:
        """A multiplexed message's page (its multiplexer's value) to send: the one ``values`` give, else the
        pages in turn, by a count of the message's frames of its own (None: not multiplexed). Not by the frame's
        counter: a counter whose modulus the number of pages does not divide (Profile 11's 0-14 with two pages)
        would send a page twice in a row when it wraps."""
        multiplexer = self._multiplexer.get(message.name)
        if multiplexer is None:
            return None
        given = values.get(multiplexer)
        if given is not None and math.isfinite(given):
            return int(given)
        pages, sent = self._pages[message.name], self._pages_sent.get(message.name, 0)
        self._pages_sent[message.name] = sent + 1
        return pages[sent % len(pages)]

    def _decode_reference(self, message: Message, data: bytes) -> DecodedFrame:  # (a frame unpadded: _unpadded)
        frame_id = message.frame_id
        if len(data) != message.length:
            raise FrameError("dlc", f"{message.name}: DLC {len(data)}, expected {message.length}")
        protection = self._protection[frame_id]
        cause = protection.cause(data)
        if cause is not None:
            raise FrameError(cause, f"{message.name}: {CAUSE_TEXT.get(cause, cause)}")
        try:
            values = cast("dict[str, float]",  # no container messages in the DBC: a dict
                          message.decode(bytes(data), decode_choices=False, scaling=True))
        except Exception as exc:  # noqa: BLE001 - cantools raises several types
            raise FrameError("malformed", f"{message.name}: {exc}") from None
        carriers = self._carriers[frame_id]
        dsg_hil = isinstance(protection, Protection)  # (its Counter and CRC ranges checked, as they always were)
        for signal in message.signals:
            if (signal.name in carriers and not dsg_hil) or signal.name not in values:  # (or another page's)
                continue
            v = values[signal.name]
            lo, hi = signal_range(signal)
            if not (lo - 1e-9 <= v <= hi + 1e-9):
                raise FrameError("range", f"{message.name}.{signal.name} = {v} outside [{lo:g}, {hi:g}]")
        counter = int(values[COUNTER]) if dsg_hil else protection.counter(data)
        return DecodedFrame(message.name, {k: float(v) for k, v in values.items() if k not in carriers}, counter)


def _padded(encode: Callable[[Mapping[str, float], int], bytes], padding: bytes, values: Mapping[str, float],
            counter: int) -> bytes:
    """A CAN FD frame's data: the message's, then ``padding`` up to the frame's length."""
    return encode(values, counter) + padding


def _unpadded(decode: Callable[[bytes], DecodedFrame], message: Message, length: int, data: bytes) -> DecodedFrame:
    """Decode a CAN FD frame of ``length`` bytes carrying ``message`` (shorter): its first bytes."""
    if len(data) != length:
        raise FrameError("dlc", f"{message.name}: DLC {len(data)}, expected {length}")
    return decode(data[:message.length])
