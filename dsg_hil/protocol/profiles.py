"""End-to-end protection per message: one interface (:class:`FrameProtection`) for every scheme a frame may carry,
and the plain table (:class:`ProtectionSpec`) that says which, as a binding's per-message ``protection`` entry or
an ARXML's E2E data gives it.

Schemes (``profile`` in the table):

* ``"none"``: no counter, no CRC; the receiver checks only DLC and ranges (and timeouts).
* ``"dsg-hil"``: this contract's own scheme, placed by the DBC's ``Counter`` and ``CRC`` signals (:mod:`.e2e`); the
  default for a message that has both signals.
* ``"P01"``, ``"P11"``: AUTOSAR E2E Profiles 1 and 11 (E2E Protocol Specification, AUTOSAR FO PRS 849). CRC-8 with
  the SAE J1850 polynomial 0x1D, init and final XOR 0x00 (:func:`.crc.crc8_p01`), over the data ID (by the data ID
  mode) and then every byte of the first ``data_length`` bits but the CRC's; a 4-bit counter 0..14 (15 is invalid);
  default layout: CRC at bit 0, counter at bit 8, the data ID's nibble (mode "nibble") at bit 12. Variants: 1A
  (data ID mode both: its low byte, then its high byte), 1B (alt: the low byte when the counter is even, else the
  high one), 1C (nibble: the low byte, then 0x00; the high byte's low nibble sent in the frame, a 12-bit data ID);
  11A (both) and 11C (nibble), which give the frames of 1A and 1C.
* ``"P02"``: Profile 2. CRC-8H2F (:func:`.crc.crc8_h2f`) over bytes 1.. of the data, then ``data_ids[counter]``
  (the 16-entry DataIDList); CRC in byte 0, the 4-bit counter 0..15 in the low nibble of byte 1 (fixed layout).
* ``"P05"``: Profile 5. CRC-16/CCITT-FALSE (:func:`.crc.crc16_ccitt`) over the data but the CRC's two bytes, then
  the 16-bit data ID, low byte first; the CRC at bit ``offset`` (little endian: low byte first), the 8-bit counter
  0..255 at ``offset`` + 16.

Bit offsets count as AUTOSAR's do: bit n is bit n % 8 (0 the least significant) of byte n // 8. The receiver
(:mod:`.validity`) takes the profile's counter modulus (16, 15 or 256) and its largest step counted as frames lost
(``max_delta_counter``, AUTOSAR's MaxDeltaCounter; default: half the modulus, rounded down, less one: 7, 7 and 127);
the frame checks say why a frame fails: "crc", "data_id" (a nibble that is not the data ID's), "counter" (a
counter value the profile never sends).

The CRCs are crccheck's (a dependency of cantools; :mod:`.crc` runs them through tables); the layouts are written
here from the specification, because the maintained implementation of the profiles, autosar-e2e, places the header
only at a byte offset with fixed relative positions and increments a counter it reads rather than writing one given:
the tests compare every profile's frames with it and with cantools' ``autosar.end_to_end`` helpers (profiles 2 and
5).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

from .crc import crc8_h2f, crc8_p01, crc16_ccitt
from .e2e import COUNTER, CRC, Protection, ProtectionError

if TYPE_CHECKING:
    from cantools.database.can import Message, Signal

__all__ = ["CAUSE_TEXT", "DATA_ID_MODES", "PROFILES", "FrameProtection", "ProfileP01", "ProfileP02", "ProfileP05",
           "ProtectionSpec", "Unprotected", "protection_for", "protection_signals", "signal_bits"]

PROFILES = ("none", "dsg-hil", "P01", "P02", "P05", "P11")
DATA_ID_MODES = ("both", "alt", "low", "nibble")
_VARIANTS = {"P01": {"1A": "both", "1B": "alt", "1C": "nibble"}, "P11": {"11A": "both", "11C": "nibble"}}
_DEFAULT_VARIANT = {"P01": "1A", "P11": "11A"}
CAUSE_TEXT = {"crc": "CRC mismatch", "data_id": "data ID mismatch", "counter": "counter value the profile never sends"}
_KEYS = {"none": (), "dsg-hil": (), "P02": ("data_ids", "data_length", "max_delta_counter"),
         "P05": ("data_id", "offset", "data_length", "max_delta_counter"),
         **dict.fromkeys(("P01", "P11"), ("variant", "data_id", "data_id_mode", "counter_offset", "crc_offset",
                                          "data_id_nibble_offset", "data_length", "max_delta_counter"))}


class FrameProtection(Protocol):
    """What the codec, the receive checks and the fault injector need of a message's protection."""

    @property
    def profile(self) -> str:
        """The scheme: one of :data:`PROFILES`."""

    @property
    def counter_modulus(self) -> int:
        """The counter counts 0 .. modulus - 1 and wraps; 0: the frame has no counter."""

    @property
    def max_delta(self) -> int:
        """The largest counter step a receiver takes as frames lost (a larger one: out of order)."""

    @property
    def layout(self) -> tuple[tuple[str, int, int], ...]:
        """The fields the protection owns: (name, bit offset, bits), names "crc", "counter", "data_id"."""

    def seal(self, data: bytes | bytearray, counter: int | None = None) -> bytes:
        """``data`` with its counter set to ``counter`` (None: as it is) and its CRC computed."""

    def cause(self, data: bytes) -> str | None:
        """Why ``data`` (of the frame's length) fails the protection ("crc", "data_id", "counter"), or None."""

    def counter(self, data: bytes) -> int:
        """The frame's counter (0 without one)."""

    def step(self, previous: int, counter: int) -> int:
        """The counter step from ``previous`` to ``counter``."""


def _read(data: bytes | bytearray, offset: int, bits: int) -> int:
    return (int.from_bytes(data, "little") >> offset) & ((1 << bits) - 1)


def _put(whole: int, offset: int, bits: int, value: int) -> int:
    """The frame ``whole`` (its bytes as one little-endian integer) with ``value`` in its ``bits`` at ``offset``."""
    mask = ((1 << bits) - 1) << offset
    return whole & ~mask | (value << offset) & mask


@dataclass(frozen=True)
class Unprotected:
    """Profile "none": no counter, no CRC."""

    length: int
    profile: str = field(default="none", init=False)
    counter_modulus: int = field(default=0, init=False)
    max_delta: int = field(default=0, init=False)
    layout: tuple[tuple[str, int, int], ...] = field(default=(), init=False)

    def seal(self, data: bytes | bytearray, counter: int | None = None) -> bytes:
        return bytes(data)

    def cause(self, data: bytes) -> str | None:
        return None

    def counter(self, data: bytes) -> int:
        return 0

    def step(self, previous: int, counter: int) -> int:
        return 1


@dataclass(frozen=True)
class _Counted:
    """What the AUTOSAR profiles share: a counter field, a CRC field, the CRC over the covered bytes."""

    data_length: int  # bits covered (AUTOSAR's DataLength)
    counter_offset: int
    crc_offset: int
    max_delta: int
    counter_bits: ClassVar[int] = 4
    crc_bits: ClassVar[int] = 8

    @property
    def layout(self) -> tuple[tuple[str, int, int], ...]:
        return (("crc", self.crc_offset, self.crc_bits), ("counter", self.counter_offset, self.counter_bits))

    @property
    def counter_modulus(self) -> int:
        return 1 << self.counter_bits

    def crc(self, data: bytes | bytearray, counter: int) -> int:
        raise NotImplementedError

    def _explicit(self, whole: int) -> int:
        """The frame ``whole`` (its bytes as one little-endian integer) with what the profile sends of its data ID
        (the nibble of P01/P11 "nibble")."""
        return whole

    def seal(self, data: bytes | bytearray, counter: int | None = None) -> bytes:
        # (per frame sent: the fields written into the frame as one integer, its bytes made twice)
        n, whole = len(data), int.from_bytes(data, "little")
        if counter is not None:
            whole = _put(whole, self.counter_offset, self.counter_bits, counter % self.counter_modulus)
        whole = self._explicit(whole)
        counted = (whole >> self.counter_offset) & ((1 << self.counter_bits) - 1)
        crc = self.crc(whole.to_bytes(n, "little"), counted)
        return _put(whole, self.crc_offset, self.crc_bits, crc).to_bytes(n, "little")

    def cause(self, data: bytes) -> str | None:
        whole = int.from_bytes(data, "little")
        counter = (whole >> self.counter_offset) & ((1 << self.counter_bits) - 1)
        if counter >= self.counter_modulus:
            return "counter"
        if self._explicit(whole) != whole:
            return "data_id"
        crc = (whole >> self.crc_offset) & ((1 << self.crc_bits) - 1)
        return None if crc == self.crc(data, counter) else "crc"

    def counter(self, data: bytes | bytearray) -> int:
        return _read(data, self.counter_offset, self.counter_bits)

    def step(self, previous: int, counter: int) -> int:
        return (counter - previous) % self.counter_modulus


@dataclass(frozen=True)
class ProfileP01(_Counted):
    """Profiles 1 and 11 (``profile``): the same frames, a 4-bit counter 0..14."""

    data_id: int
    data_id_mode: str  # DATA_ID_MODES
    data_id_nibble_offset: int
    profile: str = "P01"

    @property
    def counter_modulus(self) -> int:
        return 15

    @property
    def layout(self) -> tuple[tuple[str, int, int], ...]:
        nibble = (("data_id", self.data_id_nibble_offset, 4),) if self.data_id_mode == "nibble" else ()
        return (*super().layout, *nibble)

    def _explicit(self, whole: int) -> int:
        if self.data_id_mode != "nibble":
            return whole
        return _put(whole, self.data_id_nibble_offset, 4, (self.data_id >> 8) & 0x0F)

    def crc(self, data: bytes | bytearray, counter: int) -> int:
        low, high = self.data_id & 0xFF, self.data_id >> 8
        mode = self.data_id_mode
        head = bytes((low, high) if mode == "both" else (low,) if mode == "low" else (low, 0) if mode == "nibble"
                     else (high if counter % 2 else low,))
        k, n = self.crc_offset // 8, self.data_length // 8
        return crc8_p01(head + bytes(data[:k]) + bytes(data[k + 1:n]))


@dataclass(frozen=True)
class ProfileP02(_Counted):
    """Profile 2: the data ID of each frame picked from the DataIDList by its counter."""

    data_ids: bytes = b""
    profile: str = field(default="P02", init=False)

    def crc(self, data: bytes | bytearray, counter: int) -> int:
        return crc8_h2f(bytes(data[1:self.data_length // 8]) + bytes((self.data_ids[counter],)))


@dataclass(frozen=True)
class ProfileP05(_Counted):
    """Profile 5: a 16-bit CRC and an 8-bit counter at ``offset``."""

    data_id: int = 0
    profile: str = field(default="P05", init=False)
    counter_bits: ClassVar[int] = 8
    crc_bits: ClassVar[int] = 16

    def crc(self, data: bytes | bytearray, counter: int) -> int:
        k, n = self.crc_offset // 8, self.data_length // 8
        return crc16_ccitt(bytes(data[:k]) + bytes(data[k + 2:n]) + self.data_id.to_bytes(2, "little"))


def signal_bits(signal: Signal) -> frozenset[int]:
    """The bits a DBC signal occupies, numbered as the profiles' offsets are (bit n: bit n % 8 of byte n // 8)."""
    if signal.byte_order == "little_endian":
        return frozenset(range(signal.start, signal.start + signal.length))
    bits, position = set(), signal.start  # Motorola: from the most significant bit down, byte by byte
    for _ in range(signal.length):
        bits.add(position)
        position = position + 15 if position % 8 == 0 else position - 1
    return frozenset(bits)


def protection_signals(message: Message, protection: FrameProtection) -> frozenset[str]:
    """The message's signals that carry its protection (all their bits inside the protection's fields): not values.
    A signal partly inside a field cannot be encoded beside it: :class:`.e2e.ProtectionError`."""
    if isinstance(protection, Protection):
        return frozenset((COUNTER, CRC))
    owned: dict[int, str] = {}
    for name, offset, bits in protection.layout:
        owned.update(dict.fromkeys(range(offset, offset + bits), name))
    inside = set()
    for signal in message.signals:
        occupied = signal_bits(signal)
        shared = occupied & owned.keys()
        if shared == occupied:
            inside.add(signal.name)
        elif shared:
            what = owned[min(shared)]
            raise ProtectionError(f"{message.name}: signal {signal.name} lies partly in the {protection.profile} "
                                  f"{what} field (bits {min(shared)}..{max(shared)})")
    return frozenset(inside)


def _int(table: Mapping[str, object], key: str, where: str, lo: int, hi: int) -> int | None:
    value = table.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise ProtectionError(f"{where}: protection {key} must be a whole number, got {value!r}")
    if not lo <= value <= hi:
        raise ProtectionError(f"{where}: protection {key} must be within {lo}..{hi:#x}, got {value:#x}"
                              if hi > 255 else f"{where}: protection {key} must be within {lo}..{hi}, got {value}")
    return value


@dataclass(frozen=True)
class ProtectionSpec:
    """One message's protection as a table gives it (module docstring: the profiles and their keys), checked for
    its keys and types; :meth:`bind` checks it against the message's frame and gives its :class:`FrameProtection`.
    ``where``: whose protection, for the error messages (e.g. the message's name)."""

    profile: str
    variant: str | None = None
    data_id: int | None = None
    data_ids: tuple[int, ...] = ()
    data_id_mode: str | None = None
    counter_offset: int | None = None
    crc_offset: int | None = None
    data_id_nibble_offset: int | None = None
    offset: int | None = None
    data_length: int | None = None
    max_delta_counter: int | None = None
    where: str = field(default="protection", compare=False)

    @classmethod
    def from_table(cls, table: ProtectionSpec | Mapping[str, object], where: str) -> ProtectionSpec:
        """The spec of ``table`` (e.g. ``{"profile": "P05", "data_id": 0x1234, "offset": 0}``)."""
        if isinstance(table, ProtectionSpec):
            return table
        if not isinstance(table, Mapping):
            raise ProtectionError(f"{where}: protection must be a table with a profile key, got {table!r}")
        profile = table.get("profile")
        if profile not in PROFILES:
            raise ProtectionError(f"{where}: protection profile must be one of {', '.join(PROFILES)}, got {profile!r}")
        assert isinstance(profile, str)
        unknown = sorted(set(table) - {"profile", *_KEYS[profile]})
        if unknown:
            raise ProtectionError(f"{where}: protection key {unknown[0]!r} is not one of profile {profile}'s "
                                  f"({', '.join(('profile', *_KEYS[profile]))})")
        values: dict[str, Any] = {"profile": profile, "where": where}
        for key in ("counter_offset", "crc_offset", "data_id_nibble_offset", "offset", "data_length"):
            values[key] = _int(table, key, where, 0, 8 * 4096)
        values["data_id"] = _int(table, "data_id", where, 0, 0xFFFF)
        values["max_delta_counter"] = _int(table, "max_delta_counter", where, 1, 255)
        if profile in _VARIANTS:
            variant, mode = table.get("variant"), table.get("data_id_mode")
            if variant is not None and variant not in _VARIANTS[profile]:
                raise ProtectionError(f"{where}: protection variant must be one of {', '.join(_VARIANTS[profile])} "
                                      f"for {profile}, got {variant!r}")
            allowed = DATA_ID_MODES if profile == "P01" else tuple(_VARIANTS[profile].values())
            if mode is not None and mode not in allowed:
                raise ProtectionError(f"{where}: protection data_id_mode must be one of {', '.join(allowed)} for "
                                      f"{profile}, got {mode!r}")
            if variant is not None and mode is not None and _VARIANTS[profile][str(variant)] != mode:
                raise ProtectionError(f"{where}: protection data_id_mode {mode!r} is not variant {variant}'s "
                                      f"({_VARIANTS[profile][str(variant)]!r})")
            if variant is None and mode is None:
                variant = _DEFAULT_VARIANT[profile]
            values["variant"] = variant if variant is not None else next(
                (v for v, m in _VARIANTS[profile].items() if m == mode), None)  # (P01 "low": no variant)
            values["data_id_mode"] = mode if mode is not None else _VARIANTS[profile][str(variant)]
        if profile == "P02":
            ids = table.get("data_ids")
            if not isinstance(ids, Sequence) or isinstance(ids, str) or len(ids) != 16 or any(
                    isinstance(i, bool) or not isinstance(i, int) or not 0 <= i <= 255 for i in ids):
                raise ProtectionError(f"{where}: protection data_ids must be the 16 data IDs (0..255) of the "
                                      f"DataIDList, got {ids!r}")
            values["data_ids"] = tuple(ids)
        elif profile in ("P01", "P05", "P11") and values["data_id"] is None:
            raise ProtectionError(f"{where}: protection data_id is missing (profile {profile} needs it)")
        return cls(**values)

    @classmethod
    def from_autosar(cls, message: Message) -> ProtectionSpec | None:
        """The spec of an ARXML message's E2E data as cantools reads it (``message.autosar.e2e``: the profile's
        category, its data IDs and the protected length; offsets and the data ID mode are the profile's defaults,
        which cantools does not read), or None if it has none."""
        e2e = message.autosar.e2e if message.autosar is not None else None
        if e2e is None:
            return None
        where = f"{message.name} (ARXML E2E)"
        found = re.fullmatch(r"(?:E2E_?)?(?:PROFILE|P)[ _]?0*(\d+)[A-Z]?", (e2e.category or "").upper())
        profile = {"1": "P01", "2": "P02", "5": "P05", "11": "P11"}.get(found.group(1) if found else "")
        if profile is None:
            raise ProtectionError(f"{where}: E2E category {e2e.category!r} is not a supported profile "
                                  f"(PROFILE_01, _02, _05, _11)")
        ids = list(e2e.data_ids or ())
        table: dict[str, object] = {"profile": profile, "data_length": 8 * e2e.payload_length}
        if profile == "P02":
            table["data_ids"] = ids
        elif len(ids) == 1:
            table["data_id"] = ids[0]
        else:
            raise ProtectionError(f"{where}: profile {profile} takes one data ID, the ARXML gives {len(ids)}")
        return cls.from_table(table, where)

    def as_table(self) -> dict[str, object]:
        """The table again, only the keys set (e.g. for ``dsg-hil binding check``'s listing)."""
        out: dict[str, object] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name != "where" and value is not None and value != ():
                out[f.name] = list(value) if isinstance(value, tuple) else value
        return out

    def bind(self, message: Message) -> FrameProtection:
        """This protection on ``message``'s frame: its fields within the frame and the covered length, apart, and
        no signal partly in one (:func:`protection_signals`); else :class:`.e2e.ProtectionError`."""
        where, n = self.where, message.length
        if self.profile == "none":
            return Unprotected(n)
        if self.profile == "dsg-hil":
            return Protection.of(message)
        data_length = 8 * n if self.data_length is None else self.data_length
        if data_length % 8 or not 8 <= data_length <= 8 * n:
            raise ProtectionError(f"{where}: protection data_length {data_length} must be whole bytes within the "
                                  f"{n}-byte frame ({8 * n} bits)")
        default_delta = 7 if self.profile != "P05" else 127
        max_delta = default_delta if self.max_delta_counter is None else self.max_delta_counter
        protection: FrameProtection
        if self.profile in ("P01", "P11"):
            mode, data_id = str(self.data_id_mode), int(self.data_id or 0)
            limit = 0xFFF if mode == "nibble" else 0xFFFF  # ("low": the high byte not covered, as the PRS has it)
            if data_id > limit:
                raise ProtectionError(f"{where}: protection data_id {data_id:#x} does not fit data ID mode {mode} "
                                      f"(at most {limit:#x})")
            protection = ProfileP01(data_length, 8 if self.counter_offset is None else self.counter_offset,
                                    0 if self.crc_offset is None else self.crc_offset, max_delta, data_id, mode,
                                    12 if self.data_id_nibble_offset is None else self.data_id_nibble_offset,
                                    self.profile)
            for key, value, step in (("crc_offset", protection.crc_offset, 8),
                                     ("counter_offset", protection.counter_offset, 4),
                                     ("data_id_nibble_offset", protection.data_id_nibble_offset, 4)):
                if value % step:
                    raise ProtectionError(f"{where}: protection {key} {value} must be a multiple of {step}")
        elif self.profile == "P02":
            protection = ProfileP02(data_length, 8, 0, max_delta, bytes(self.data_ids))
        else:
            offset = 0 if self.offset is None else self.offset
            if offset % 8:
                raise ProtectionError(f"{where}: protection offset {offset} must be a multiple of 8")
            protection = ProfileP05(data_length, offset + 16, offset, max_delta, int(self.data_id or 0))
        if not 1 <= max_delta < protection.counter_modulus:
            raise ProtectionError(f"{where}: protection max_delta_counter {max_delta} must be within 1.."
                                  f"{protection.counter_modulus - 1}")
        spans = sorted((offset, offset + bits, name) for name, offset, bits in protection.layout)
        for offset, end, name in spans:
            if end > data_length:
                raise ProtectionError(f"{where}: the {self.profile} {name} field (bits {offset}..{end - 1}) does not "
                                      f"fit the {data_length} bits covered of the {n}-byte frame")
        for (_, end, first), (offset, _, second) in zip(spans, spans[1:]):
            if offset < end:
                raise ProtectionError(f"{where}: the {self.profile} {first} and {second} fields overlap")
        protection_signals(message, protection)
        return protection


def protection_for(message: Message, spec: ProtectionSpec | Mapping[str, object] | None = None) -> FrameProtection:
    """``message``'s protection: ``spec`` (a table or spec) if given, else the ARXML's E2E data if it has some, else
    the dsg-hil scheme on its ``Counter`` and ``CRC`` signals (:class:`.e2e.ProtectionError` without them)."""
    if spec is not None:
        return ProtectionSpec.from_table(spec, message.name).bind(message)
    arxml = ProtectionSpec.from_autosar(message)
    return arxml.bind(message) if arxml is not None else Protection.of(message)
