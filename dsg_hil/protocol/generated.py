"""Per-message encode and decode functions generated from the DBC at start-up: plain integer and bit operations,
with every scale, offset, range, bit position and the Counter/CRC positions read from the DBC message.

They do exactly what the cantools path of :class:`.codec.Codec` does (clamp to the DBC range, encode as cantools
does with ``strict=True``, seal the CRC; decode rejecting a wrong DLC, CRC or a value out of range with the same
reasons and messages), byte for byte: a test checks both on thousands of random and corrupted frames. cantools
still loads and validates the DBC and is the reference; a message with something this generator does not cover
(multiplexing, float signals, a range its bits cannot carry, a Counter or CRC that is not a plain integer) gets
no generated functions, and the codec keeps the cantools path for it. A message under another protection than the
dsg-hil scheme (:mod:`.profiles`) has the signals that carry it left out, and its protection's own ``seal`` and
``cause`` called by the generated functions instead of the CRC written into them.

Why generated source (``exec``) rather than a loop over signal descriptions: one Python function per message
with its constants inlined runs in about 1 us per frame, a generic loop several times that; the source of each
function is kept (``source``) for reading and debugging. Compiled by mypyc the loop is the faster (:mod:`.plan`):
:func:`plan` gives it the numbers the source inlines, and the codec runs it in the compiled build.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import CodeType
from typing import Any, cast

from cantools.database.can import Message, Signal
from cantools.database.conversion import BaseConversion, IdentityConversion, LinearIntegerConversion

from .e2e import COUNTER, CRC, Protection
from .profiles import CAUSE_TEXT, FrameProtection, protection_signals
from .plan import IDENTITY, LINEAR_INTEGER, SCALED, SCALED_OFFSET, MessagePlan, SignalPlan
from .ranges import raw_range, signal_range

__all__ = ["Decoder", "Encoder", "GeneratedMessage", "dict_of", "generate", "generate_fused", "generate_planned",
           "plan", "unsupported"]

Encoder = Callable[[Mapping[str, float], int], bytes]
DEFAULT = "<default>"  # _encode_lines: a signal a fused encoder is given no value for
Decoder = Callable[[bytes], Any]  # a DecodedFrame of .codec


@dataclass(frozen=True)
class GeneratedMessage:
    """The generated functions of one message and their source."""

    encode: Encoder  # (values, counter) -> frame data
    decode: Decoder  # data -> DecodedFrame, or FrameError
    source: str


def _conversion(signal: Signal) -> BaseConversion:
    """The numeric conversion cantools uses for ``signal`` (without its value table, as ``decode_choices=False``)."""
    return BaseConversion.factory(scale=signal.scale, offset=signal.offset, choices=None, is_float=signal.is_float)


def _to_raw(conversion: BaseConversion) -> list[str]:
    """Source lines of cantools' ``numeric_scaled_to_raw`` for ``conversion``: from ``v`` to the integer ``r``."""
    if isinstance(conversion, IdentityConversion):
        return ["    r = round(v)"]
    if isinstance(conversion, LinearIntegerConversion):  # divmod first, as cantools does (exact when it can)
        return [f"    d = v{_minus(conversion.offset)}", f"    q, m = divmod(d, {conversion.scale!r})",
                f"    r = round(q) if m == 0 else round(d / {conversion.scale!r})"]
    if not conversion.offset:
        return [f"    r = round(v / {conversion.scale!r})"]
    return [f"    r = round((v - {conversion.offset!r}) / {conversion.scale!r})"]


def _minus(offset: float) -> str:
    """Source subtracting ``offset``; nothing for 0 (x - 0 is x for every float, -0.0 included)."""
    return f" - {offset!r}" if offset else ""


def _to_physical(conversion: BaseConversion, raw: str) -> str:
    """Source of cantools' ``raw_to_scaled`` (no value table) applied to the expression ``raw``."""
    if isinstance(conversion, IdentityConversion):
        return raw
    if not conversion.offset and not (isinstance(conversion.scale, float) and conversion.scale < 0):
        return f"{raw} * {conversion.scale!r}"  # + 0 changes nothing but the -0.0 of a negative scale
    return f"{raw} * {conversion.scale!r} + {conversion.offset!r}"


def _raw_of(conversion: BaseConversion, value: float) -> int:
    return int(conversion.numeric_scaled_to_raw(value))


def _fits(signal: Signal, raw: int) -> bool:
    if signal.is_signed:
        return -(1 << (signal.length - 1)) <= raw < (1 << (signal.length - 1))
    return 0 <= raw < (1 << signal.length)


def _shift(signal: Signal, length: int) -> tuple[str, int]:
    """("F" or "G", shift): the signal's least significant bit in the frame read as a little-endian integer (F,
    Intel signals) or as a big-endian one (G, Motorola signals, whose DBC start bit is their most significant)."""
    if signal.byte_order == "little_endian":
        return "F", signal.start
    msb_from_left = 8 * (signal.start // 8) + (7 - signal.start % 8)
    return "G", 8 * length - msb_from_left - signal.length


def unsupported(message: Message, protection: FrameProtection) -> str | None:
    """Why no functions are generated for ``message`` (the codec then keeps cantools), or None."""
    if message.is_container or message.is_multiplexed():
        return "multiplexed or container message"
    carriers = protection_signals(message, protection)
    for signal in message.signals:
        if signal.is_float:
            return f"{signal.name} is a float signal"
        if signal.multiplexer_ids or signal.is_multiplexer:
            return f"{signal.name} is multiplexed"
        if signal.name in carriers and not isinstance(protection, Protection):
            continue  # (the profile's own fields: sealed and read by the protection, not as signals)
        if signal.name in (COUNTER, CRC):
            if not isinstance(_conversion(signal), IdentityConversion):
                return f"{signal.name} is scaled"
            top = protection.counter_modulus - 1 if signal.name == COUNTER else 0
            if (signal.minimum is not None and signal.minimum > 0) or (signal.maximum is not None
                                                                       and signal.maximum < top):
                return f"{signal.name}'s DBC range does not hold 0..{top}"
            continue
        lo, hi = signal_range(signal)
        if signal.initial is not None and type(signal.initial) not in (int, float):
            return f"{signal.name}'s initial value is not a number"
        conversion = _conversion(signal)
        if not (_fits(signal, _raw_of(conversion, lo)) and _fits(signal, _raw_of(conversion, hi))):
            return f"{signal.name}'s DBC range [{lo:g}, {hi:g}] does not fit its {signal.length} bits"
    return None


def generate(message: Message, protection: FrameProtection, frame_error: type,
             decoded_frame: type) -> GeneratedMessage:
    """The encode and decode functions of ``message`` (check :func:`unsupported` first); decode raises
    ``frame_error`` and returns a ``decoded_frame``, a NamedTuple of (name, values, counter). The dsg-hil scheme's
    counter and CRC are written into the source; another profile's are the protection's own ``seal``, ``cause``
    and ``counter`` (:mod:`.profiles`), called by it, its signals (:func:`.profiles.protection_signals`) left out."""
    name, length = message.name, message.length
    enc = ["def encode(values, counter):", "    get = values.get", "    F = G = 0"]
    dec = ["def decode(data):",
           f"    if len(data) != {length}:",
           f"        raise FrameError('dlc', f'{name}: DLC {{len(data)}}, expected {length}')"]
    crc_tables: dict[str, Any]
    if isinstance(protection, Protection):
        crc, crc_tables = _crc_expression(protection)
        dec += ["    F = from_bytes(data, 'little')",
                f"    if {_field('F', 8 * protection.crc_byte, 255)} != {crc}:",
                f"        raise FrameError('crc', '{name}: CRC mismatch')"]
    else:
        crc_tables = {"CAUSE": protection.cause, "COUNTER_OF": protection.counter, "SEAL": protection.seal}
        dec += ["    c = CAUSE(data)", "    if c is not None:",
                f"        raise FrameError(c, {name + ': '!r} + TEXT.get(c, c))", "    F = from_bytes(data, 'little')"]
    carriers = protection_signals(message, protection)
    if any(s.byte_order == "big_endian" for s in message.signals):
        dec.append("    G = from_bytes(data, 'big')")
    out = []
    for i, signal in enumerate(message.signals):
        conversion = _conversion(signal)
        acc, shift = _shift(signal, length)
        mask = (1 << signal.length) - 1
        lo, hi = signal_range(signal)
        if signal.name in carriers and not isinstance(protection, Protection):
            continue
        enc += _encode_lines(signal, protection, length)
        # decode: from the frame, to physical, range check
        checked = _checked(signal)
        if signal.name == CRC and not checked and isinstance(protection, Protection):
            continue  # checked above, its value not returned
        dec.append(f"    r = {_field(acc, shift, mask)}")
        if signal.is_signed:
            dec.append(f"    if r & {1 << (signal.length - 1)}:\n        r -= {1 << signal.length}")
        dec.append(f"    v{i} = {_to_physical(conversion, 'r')}")
        if checked:
            dec += [f"    if not ({lo - 1e-9!r} <= v{i} <= {hi + 1e-9!r}):",
                    f"        raise FrameError('range', f'{name}.{signal.name} = {{v{i}}} outside [{lo:g}, {hi:g}]')"]
        if signal.name not in (COUNTER, CRC) or not isinstance(protection, Protection):
            out.append(f"{signal.name!r}: {_as_float(conversion, f'v{i}')}")
    counter = "COUNTER_OF(data)" if not isinstance(protection, Protection) else \
        f"v{next(i for i, s in enumerate(message.signals) if s.name == COUNTER)}"
    # DecodedFrame(...) without its Python-level __new__ (a NamedTuple's is tuple.__new__ with the fields)
    dec.append(f"    return NEW(DecodedFrame, ({name!r}, {{{', '.join(out)}}}, {counter}))")  # an int counter
    enc += _encode_end(message, protection)
    source = "\n".join(enc) + "\n\n\n" + "\n".join(dec) + "\n"
    namespace: dict = {"FrameError": frame_error, "DecodedFrame": decoded_frame, "INF": math.inf,
                       "from_bytes": int.from_bytes, "NEW": tuple.__new__, "TEXT": CAUSE_TEXT,
                       **crc_tables}  # each looked up once
    exec(_compiled(source, name), namespace)  # noqa: S102 - our own source
    return GeneratedMessage(namespace["encode"], namespace["decode"], source)


def plan(message: Message, protection: Protection, frame_error: type, decoded_frame: type) -> MessagePlan | None:
    """The plan of ``message`` (check :func:`unsupported` first): the numbers :func:`generate` writes into its
    source, for :class:`.plan.MessagePlan` to run (compiled: the codec's choice there, :data:`.plan.COMPILED`).
    None where a bound, scale or offset is an integer no float holds (beyond 2**53: the source compares and
    computes with the integer), which keeps the generated functions."""
    length, k = message.length, protection.crc_byte
    values: list[SignalPlan] = []
    counter = crc = None
    order = []
    for signal in message.signals:
        conversion = _conversion(signal)
        big, shift = _shift(signal, length)
        lo, hi = signal_range(signal)
        scale, offset = conversion.scale, conversion.offset
        if any(float(x) != x for x in (lo, hi, scale, offset)):  # a float compares and computes otherwise
            return None
        kind = (IDENTITY if isinstance(conversion, IdentityConversion) else LINEAR_INTEGER
                if isinstance(conversion, LinearIntegerConversion) else SCALED if not offset else SCALED_OFFSET)
        int_values = not isinstance(scale, float) and not isinstance(offset, float)  # :func:`_to_physical` in ints
        default = _default(signal) if signal.name not in (COUNTER, CRC) else 0.0
        s = SignalPlan(signal.name, big == "G", shift, signal.length, signal.is_signed, kind, float(scale),
                       float(offset), int_values, bool(offset) or (isinstance(scale, float) and scale < 0),
                       float(lo), float(hi), default, _checked(signal))
        if signal.name == COUNTER:
            counter, index = s, -1
        elif signal.name == CRC:
            if not s.checked:
                continue  # (its value checked as the CRC, not returned)
            crc, index = s, -2
        else:
            values.append(s)
            index = len(values) - 1
        order.append(index)
    assert counter is not None  # (Protection.of: every protected message has one)
    constant, terms = _crc_terms(protection)
    return MessagePlan(message.name, length, values, counter, protection.counter_modulus, 8 * k, constant,
                       [(table, shift, mask) for _, table, shift, mask in terms], crc, frame_error, decoded_frame,
                       order)


def _encode_lines(signal: Signal, protection: FrameProtection, length: int, value: str | None = None,
                  is_float: bool = False) -> list[str]:
    """Source lines putting ``signal`` into the frame (``F`` or ``G``): clamped (NaN or missing: the default), to
    raw. Its value is ``values.get(name)`` (``get``; None: missing), or the expression ``value`` (never missing;
    ``is_float``: a float already, else taken as one), or with ``value`` :data:`DEFAULT` its default; the dsg-hil
    scheme's Counter is ``counter``, its CRC sealed after all (another profile's signals are not given here)."""
    acc, shift = _shift(signal, length)
    mask = (1 << signal.length) - 1
    if signal.name == COUNTER and isinstance(protection, Protection):
        return [f"    {acc} |= ((counter % {protection.counter_modulus}) & {mask}){_shifted(shift)}"]
    if signal.name == CRC and isinstance(protection, Protection):
        return []
    lo, hi = signal_range(signal)
    default = _default(signal)
    clamp = [f"if not {_compared(lo)} <= v <= {_compared(hi)}:",  # a value in range: two comparisons, no more
             f"    v = {default!r} if v != v or v == INF or v == -INF else {lo!r} if v < {_compared(lo)} else {hi!r}"]
    if value is None:
        lines = [f"    v = get({signal.name!r})", "    if v is None:", f"        v = {default!r}", "    else:",
                 "        v = float(v)", *(f"        {line}" for line in clamp)]
    elif value == DEFAULT:
        lines = [f"    v = {default!r}"]
    else:
        lines = [f"    v = {value}" if is_float else f"    v = float({value})", *(f"    {line}" for line in clamp)]
    return [*lines, *_to_raw(_conversion(signal)), f"    {acc} |= (r & {mask}){_shifted(shift)}"]


def _encode_end(message: Message, protection: FrameProtection) -> list[str]:
    """The last source lines of an encoder: big-endian signals moved in, the CRC sealed, the frame's bytes (another
    profile than dsg-hil's: its ``seal`` of them, with the counter)."""
    length = message.length
    lines = []
    if any(s.byte_order == "big_endian" for s in message.signals):
        lines.append(f"    F |= from_bytes(G.to_bytes({length}, 'big'), 'little')")
    if not isinstance(protection, Protection):
        return [*lines, f"    return SEAL(F.to_bytes({length}, 'little'), counter)"]
    crc, _ = _crc_expression(protection)
    return [*lines, f"    return (F | ({crc}){_shifted(8 * protection.crc_byte)}).to_bytes({length}, 'little')"]


def _namespace(protection: FrameProtection) -> dict[str, Any]:
    """What an encoder's source looks up for its protection: the dsg-hil scheme's CRC tables, another's seal."""
    return _crc_expression(protection)[1] if isinstance(protection, Protection) else {"SEAL": protection.seal}


def generate_fused(message: Message, protection: FrameProtection, args: Sequence[str], values: Mapping[str, str],
                   namespace: Mapping[str, object] | None = None, *,
                   floats: bool = False) -> tuple[Callable[..., bytes], str]:
    """An encoder of ``message`` (check :func:`unsupported` first) taking ``args`` and then the counter, whose
    signal values are the Python expressions ``values`` of those arguments (by signal; a signal not named takes its
    default, as one missing from the dict of the plain encoder): the frame the plain encoder gives for
    ``{signal: float(expression)}``, byte for byte, without the dict built and looked up. ``namespace``: names the
    expressions use besides ``args``; ``floats``: every expression gives a float (else each is taken as
    ``float(expression)``). Returns the function and its source."""
    carriers = protection_signals(message, protection)
    _check_expressions(message, args, values, carriers)
    lines = [f"def encode({', '.join((*args, 'counter'))}):", "    F = G = 0"]
    for signal in message.signals:
        if signal.name not in carriers or isinstance(protection, Protection):
            lines += _encode_lines(signal, protection, message.length, values.get(signal.name, DEFAULT), floats)
    source = "\n".join([*lines, *_encode_end(message, protection)]) + "\n"
    scope: dict = {"INF": math.inf, "from_bytes": int.from_bytes, **_namespace(protection), **(namespace or {})}
    exec(_compiled(source, f"{message.name} fused"), scope)  # noqa: S102 - our own source
    return scope["encode"], source


def _check_expressions(message: Message, args: Sequence[str], values: Mapping[str, str],
                       carriers: frozenset[str] = frozenset((COUNTER, CRC))) -> None:
    """A ValueError for a value given to no signal of ``message`` (or to one that carries its protection, e.g. its
    Counter or CRC), or an argument named as a name the generated encoders use."""
    unknown = set(values) - {s.name for s in message.signals} | set(values) & carriers
    if unknown:
        raise ValueError(f"{message.name}: no signal {sorted(unknown)[0]} to give a value")
    taken = set(args) & {"F", "G", "v", "r", "d", "q", "m", "counter", "INF", "from_bytes", "ENCODE", "SEAL"}
    if taken:
        raise ValueError(f"{message.name}: argument {sorted(taken)[0]!r} is a name the encoder uses")


def generate_planned(message: Message, message_plan: MessagePlan, args: Sequence[str], values: Mapping[str, str],
                     namespace: Mapping[str, object] | None = None, *,
                     floats: bool = False) -> tuple[Callable[..., bytes], str]:
    """:func:`generate_fused`'s encoder run by ``message_plan`` (:meth:`.plan.MessagePlan.encode_values`): the
    generated part only the expressions, as a tuple of floats (a signal not named: its default, which its clamp
    leaves as it is; ``float()`` of each unless ``floats``). The same bytes; the codec's choice where the plan runs
    compiled. Returns the function and its source."""
    _check_expressions(message, args, values)
    items = []
    for s in message_plan.values:
        value = values.get(s.name)
        items.append(repr(s.default) if value is None else f"({value})" if floats else f"float({value})")
    source = (f"def encode({', '.join((*args, 'counter'))}):\n"
              f"    return ENCODE(({', '.join(items)}{',' if len(items) == 1 else ''}), counter)\n")
    scope: dict = {**(namespace or {}), "ENCODE": message_plan.encode_values}
    exec(_compiled(source, f"{message.name} planned"), scope)  # noqa: S102 - our own source
    return scope["encode"], source


def dict_of(args: Sequence[str], values: Mapping[str, str],
            namespace: Mapping[str, object] | None = None) -> Callable[..., dict[str, float]]:
    """``f(*args)``: the dict ``{signal: expression}`` of ``values`` (the input of a plain encoder, for a message
    with no fused one)."""
    items = ", ".join(f"{signal!r}: {value}" for signal, value in values.items())
    source = f"def values({', '.join(args)}):\n    return {{{items}}}\n"
    scope: dict = dict(namespace or {})
    exec(_compiled(source, "values"), scope)  # noqa: S102 - our own source
    return scope["values"]


def _clamped(default: float, lo: float, hi: float) -> float:
    """A missing or non-finite value's replacement as the cantools path has it: float, then clamped."""
    v = float(default)
    if v < lo:
        v = lo
    if v > hi:
        v = hi
    return v


def _default(signal: Signal) -> float:
    """A value signal's default, a missing or non-finite value's replacement: its initial value, else 0, clamped to
    its range (a number: see :func:`unsupported`)."""
    lo, hi = signal_range(signal)
    return _clamped(cast(float, signal.initial) if signal.initial is not None else min(max(0.0, lo), hi), lo, hi)


def _checked(signal: Signal) -> bool:
    """Whether decoding checks the signal's DBC range: some value its bits carry is outside it."""
    lo, hi = signal_range(signal)
    bits_lo, bits_hi = raw_range(signal)
    return not lo - 1e-9 <= bits_lo <= bits_hi <= hi + 1e-9


def _compared(bound: float) -> str:
    """Source of a range bound that a float is compared with: as a float when that is exact (a float compares
    with a float faster than with an int, and to the same result)."""
    return repr(float(bound)) if float(bound) == bound else repr(bound)


def _shifted(shift: int) -> str:
    return f" << {shift}" if shift else ""


def _field(acc: str, shift: int, mask: int) -> str:
    """Source of the bits ``mask`` at ``shift`` of the integer ``acc``."""
    return f"({acc} >> {shift}) & {mask}" if shift else f"{acc} & {mask}"


def _as_float(conversion: BaseConversion, value: str) -> str:
    """``float(value)``, written only where the conversion can give an int (a float scale gives floats)."""
    return value if isinstance(conversion.scale, float) else f"float({value})"


def _crc_expression(protection: Protection) -> tuple[str, dict[str, bytes]]:
    """Source of the frame's CRC (final XOR included) from ``F``, its data as a little-endian integer with the
    CRC byte ignored, and the tables it reads (:func:`_crc_terms`)."""
    constant, terms = _crc_terms(protection)
    source = " ^ ".join([str(constant), *(f"{name}[{_field('F', shift, mask)}]" for name, _, shift, mask in terms)])
    return source, {name: table for name, table, _, _ in terms}


def _crc_terms(protection: Protection) -> tuple[int, list[tuple[str, bytes, int, int]]]:
    """The frame's CRC (final XOR included) as a constant XOR table look-ups of ``F``, its data as a little-endian
    integer with the CRC byte ignored: (constant, [(name, table, shift, mask)]). The CRC is affine in the data bytes
    (the table of a CRC without reflection is linear: T[a ^ b] = T[a] ^ T[b]), so it is a constant (the frame ID's
    bytes, then zeros) XOR what each data byte contributes given how many covered bytes follow it
    (:func:`_byte_contribution`); two neighbouring data bytes are looked up as one 16-bit index
    (:func:`_pair_contribution`): 4 look-ups for a frame of 8 bytes instead of 7 steps of the register."""
    from .crc import _TABLE  # noqa: PLC0415

    covered = [p for p in range(protection.length) if p != protection.crc_byte]
    following = {p: len(covered) - 1 - q for q, p in enumerate(covered)}  # covered bytes after byte p
    constant = _crc_after_header(protection)
    for _ in covered:
        constant = _TABLE[constant]
    terms, p = [], 0
    while p < protection.length:
        if p not in following:
            p += 1
        elif p + 1 in following:
            a, b = following[p], following[p + 1]
            terms.append((f"P{a}_{b}", _pair_contribution(a, b), 8 * p, 0xFFFF))
            p += 2
        else:
            terms.append((f"L{following[p]}", _byte_contribution(following[p]), 8 * p, 255))
            p += 1
    return constant ^ 0xFF, terms


@functools.lru_cache(maxsize=64)
def _byte_contribution(following: int) -> bytes:
    """What a data byte adds (XOR) to the CRC register when ``following`` more bytes follow it, by its value."""
    from .crc import _TABLE  # noqa: PLC0415

    table = []
    for byte in range(256):
        crc = _TABLE[byte]
        for _ in range(following):
            crc = _TABLE[crc]
        table.append(crc)
    return bytes(table)


@functools.lru_cache(maxsize=64)
def _pair_contribution(low_following: int, high_following: int) -> bytes:
    """:func:`_byte_contribution` of two neighbouring bytes at once, by low byte + 256 x high byte (64 KiB)."""
    low, high = _byte_contribution(low_following), _byte_contribution(high_following)
    return b"".join(low.translate(_xor_with(h)) for h in high)


@functools.lru_cache(maxsize=256)
def _xor_with(c: int) -> bytes:
    """A ``bytes.translate`` table giving x ^ c for every byte x."""
    return bytes(x ^ c for x in range(256))


@functools.lru_cache(maxsize=256)
def _compiled(source: str, name: str) -> CodeType:
    """The source compiled once per process (every codec of the same DBC generates the same source)."""
    return compile(source, f"<dsg_hil codec: {name}>", "exec")


def _crc_after_header(protection: Protection) -> int:
    """The CRC register after the frame ID's two bytes, which every frame of the message starts with."""
    from .crc import _TABLE  # noqa: PLC0415

    crc = 0xFF
    for byte in (protection.frame_id & 0xFF, (protection.frame_id >> 8) & 0xFF):
        crc = _TABLE[crc ^ byte]
    return crc
