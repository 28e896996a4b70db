"""The diagnostic contract (UDS, ISO 14229-1, on ISO-TP, ISO 15765-2): request/response CAN IDs and the one table of
data identifiers (DIDs) and trouble codes (DTCs), as data (``dsg_hil/data/diag.toml``, a user's ECU: a file of the
same form). ecu-stub serves it; ``dsg-hil diag`` and the test fixture's UDS client decode with it.

A DID's value is its fields packed big-endian, each ``raw = round((physical - offset) / scale)``; a DTC is three
bytes, SAE J2012: the two letter bits (P 00, C 01, B 10, U 11), the code's four hex digits, failure type 00.
"""

from __future__ import annotations

import struct
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from cantools.database import Database

from ..common.errors import InputError
from ..common.files import read_input_file

__all__ = ["DEFAULT_DIAG", "DTC_LETTERS", "DiagDescription", "DiagError", "Did", "DidField", "Dtc", "diag_ids",
           "dtc_code", "dtc_number", "load_description"]

DEFAULT_DIAG = resources.files("dsg_hil") / "data" / "diag.toml"
TYPES = {"u8": ">B", "u16": ">H", "s16": ">h", "u32": ">I"}
DTC_LETTERS = "PCBU"


class DiagError(InputError):
    """A description file (or diag IDs) that cannot be used."""


@dataclass(frozen=True)
class DidField:
    name: str
    type: str
    scale: float
    offset: float
    unit: str

    @property
    def size(self) -> int:
        return struct.calcsize(TYPES[self.type])

    def encode(self, value: float) -> bytes:
        """``value`` [unit] -> raw bytes, clamped to the type's range (a sensor's full scale)."""
        fmt = TYPES[self.type]
        bits = 8 * self.size
        low, high = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if fmt[1].islower() else (0, (1 << bits) - 1)
        raw = round((value - self.offset) / self.scale) if value == value else 0  # NaN: 0
        return struct.pack(fmt, min(max(raw, low), high))

    def decode(self, data: bytes) -> float:
        return struct.unpack(TYPES[self.type], data)[0] * self.scale + self.offset


@dataclass(frozen=True)
class Did:
    """A data identifier: ``ascii`` text of ``length`` bytes, or ``fields`` (physical values)."""

    id: int
    name: str
    fields: tuple[DidField, ...] = ()
    ascii_length: int = 0

    @property
    def size(self) -> int:
        return self.ascii_length or sum(f.size for f in self.fields)

    def encode(self, value: Mapping[str, float] | str) -> bytes:
        if self.ascii_length:
            text = value if isinstance(value, str) else ""
            return text.encode("ascii", "replace")[: self.ascii_length].ljust(self.ascii_length, b" ")
        assert not isinstance(value, str)
        return b"".join(f.encode(value.get(f.name, float("nan"))) for f in self.fields)

    def decode(self, data: bytes) -> dict[str, float] | str:
        """Bytes -> ``{field: value}`` (or the text); :class:`DiagError` when the length is not the DID's."""
        if len(data) != self.size:
            raise DiagError(f"DID 0x{self.id:04X} {self.name}: {len(data)} bytes, expected {self.size}")
        if self.ascii_length:
            return data.decode("ascii", "replace").rstrip(" \x00")
        values, at = {}, 0
        for f in self.fields:
            values[f.name] = f.decode(data[at:at + f.size])
            at += f.size
        return values


@dataclass(frozen=True)
class Dtc:
    """A trouble code: ``number`` (3 bytes), ``code`` (``P1701``), what sets it (``monitor``) after ``debounce``
    failing control periods in a row."""

    number: int
    code: str
    name: str
    monitor: str
    debounce: int
    text: str


@dataclass(frozen=True)
class DiagDescription:
    dids: Mapping[int, Did]
    dtcs: Sequence[Dtc]
    snapshot: tuple[int, ...]
    request_id: int | None = None
    response_id: int | None = None

    def dtc(self, number: int) -> Dtc | None:
        return next((d for d in self.dtcs if d.number == number), None)


def dtc_number(code: str) -> int:
    """``P1701`` -> 0x170100 (SAE J2012: letter bits, four hex digits, failure type 00)."""
    text = code.strip().upper()
    if len(text) != 5 or text[0] not in DTC_LETTERS or any(c not in "0123456789ABCDEF" for c in text[1:]) \
            or text[1] not in "0123":
        raise DiagError(f"DTC code {code!r}: expected a letter P/C/B/U and four hex digits, the first 0-3")
    return ((DTC_LETTERS.index(text[0]) << 14) | int(text[1:], 16)) << 8


def dtc_code(number: int) -> str:
    """0x170100 -> ``P1701`` (the failure type byte shown as ``-XX`` when not 00)."""
    high = number >> 8
    code = f"{DTC_LETTERS[(high >> 14) & 3]}{high & 0x3FFF:04X}"
    return code if number & 0xFF == 0 else f"{code}-{number & 0xFF:02X}"


def diag_ids(db: Database) -> tuple[int, int]:
    """The request and response CAN IDs of the DBC's network attributes ``DiagRequestId`` / ``DiagResponseId``."""
    attributes = db.dbc.attributes if db.dbc is not None else {}
    try:
        return int(attributes["DiagRequestId"].value), int(attributes["DiagResponseId"].value)
    except KeyError as exc:
        raise DiagError(f"DBC: no network attribute {exc.args[0]} (the UDS request/response IDs)") from None


def load_description(path: str | Path | None = None) -> DiagDescription:
    """Read a description file (None: ecu-stub's, :data:`DEFAULT_DIAG`); :class:`DiagError` names the file and key."""
    where = Path(str(path)) if path is not None else Path(str(DEFAULT_DIAG))
    text = read_input_file(where, "diag description", DiagError)
    try:
        return _parse(tomllib.loads(text))
    except tomllib.TOMLDecodeError as exc:
        raise DiagError(f"{where}: not valid TOML: {exc}") from None
    except (KeyError, TypeError, ValueError) as exc:
        message = str(exc) if isinstance(exc, DiagError) else f"{type(exc).__name__} {exc}"
        raise DiagError(f"{where}: {message}") from None


def _int(entry: Mapping[str, Any], key: str, low: int, high: int, what: str) -> int:
    value = entry.get(key)
    if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
        raise DiagError(f"{what}: {key} must be an integer {low}-{high}, not {value!r}")
    return value


def _parse(data: Mapping[str, Any]) -> DiagDescription:
    dids: dict[int, Did] = {}
    for n, entry in enumerate(data.get("did", [])):
        what = f"did[{n}]"
        did_id = _int(entry, "id", 0, 0xFFFF, what)
        name = str(entry.get("name", f"0x{did_id:04X}"))
        if did_id in dids:
            raise DiagError(f"{what}: id 0x{did_id:04X} given twice")
        if entry.get("kind") == "ascii":
            dids[did_id] = Did(did_id, name, ascii_length=_int(entry, "length", 1, 255, what))
            continue
        fields = []
        for k, f in enumerate(entry.get("fields") or ()):
            if f.get("type") not in TYPES:
                raise DiagError(f"{what}.fields[{k}]: type must be one of {', '.join(TYPES)}, not {f.get('type')!r}")
            scale = float(f.get("scale", 1.0))
            if scale == 0.0:
                raise DiagError(f"{what}.fields[{k}]: scale must not be 0")
            fields.append(DidField(str(f["name"]), f["type"], scale, float(f.get("offset", 0.0)),
                                   str(f.get("unit", "-"))))
        if not fields:
            raise DiagError(f"{what}: give kind = \"ascii\" with a length, or fields")
        dids[did_id] = Did(did_id, name, tuple(fields))
    dtcs = []
    for n, entry in enumerate(data.get("dtc", [])):
        what = f"dtc[{n}]"
        try:
            number = dtc_number(str(entry["code"]))
        except DiagError as exc:
            raise DiagError(f"{what}: {exc}") from None
        dtcs.append(Dtc(number, dtc_code(number), str(entry.get("name", entry["code"])), str(entry.get("monitor", "")),
                        _int(entry, "debounce", 1, 10000, what) if "debounce" in entry else 1,
                        str(entry.get("text", ""))))
    if len({d.number for d in dtcs}) != len(dtcs):
        raise DiagError("dtc: a code given twice")
    snapshot = tuple(data.get("snapshot", ()))
    unknown = [s for s in snapshot if s not in dids]
    if unknown:
        raise DiagError(f"snapshot: DID {unknown[0]!r} is not described in [[did]]")
    ids = [_int(data, k, 0, 0x7FF, k) if k in data else None for k in ("request_id", "response_id")]
    return DiagDescription(dids, tuple(dtcs), snapshot, ids[0], ids[1])
