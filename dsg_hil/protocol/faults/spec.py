"""Declarative fault specifications: what to do to which DBC message or signal, and when.

One fault is a :class:`FaultSpec`. It comes from a scenario TOML table, a command-line string or Python::

    [[fault]]                                   # scenario TOML
    kind = "drop"                               # see KINDS
    target = "TCU_CMD"                          # MESSAGE or MESSAGE.Signal (signal faults); none for "flood"
    start_s = 10.0                              # window [start_s, end_s) in the sender's time (simulated in lockstep)
    end_s = 12.0
    probability = 0.5                           # share of the frames in the window that are hit (default 1)
    side = "tcu"                                # whose frames: "plant" or "tcu" (default: the message's DBC sender)

    --fault 'drop:TCU_CMD@10-12,probability=0.5'           # the same on the command line
    --fault 'stuck:PLANT_VEHICLE.VehicleSpeed@40-45,value=0'
    --fault 'flood@5-15,rate=20,frame_id=0x5A5'

Keys besides kind, target and the window: ``probability`` (all kinds), ``delay_s`` (delay), ``value`` (stuck: the
value held; offset: what is added, in the signal's DBC unit; gain: the non-zero factor the physical value is
multiplied by), ``dlc`` (wrong_dlc: the frame's length in bytes, default 7; 0-8, and on a CAN FD message also
12, 16, 20, 24, 32, 48 or 64), ``rate`` (flood: unknown-ID frames per frame the node sends, default 10),
``frame_id`` (flood, default 0x5A5; must not be in the DBC), ``side`` (the node whose sent frames are changed;
default: the DBC sender of the target message, "plant" for flood).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from cantools.database.can import Database, Signal

from ...common.errors import InputError

__all__ = ["CLASSIC_LENGTHS", "FD_LENGTHS", "FaultError", "FaultSpec", "KINDS", "SIDES", "SIGNAL_KINDS",
           "check_against_dbc", "check_faults",
           "fault_from_mapping", "fault_side", "parse_fault"]

KINDS = {
    "drop": "the frame is not sent",
    "delay": "the frame is held for delay_s, then sent",
    "duplicate": "the frame is sent twice",
    "corrupt_crc": "the CRC's bits are inverted (any profile with a CRC)",
    "freeze_counter": "the counter keeps the value it had when the window opened (CRC recomputed; any profile with "
                      "a counter)",
    "stuck": "the signal holds `value` (CRC and counter valid)",
    "offset": "`value` is added to the signal (CRC and counter valid)",
    "gain": "the signal's physical value is multiplied by `value` (CRC and counter valid)",
    "out_of_range": "the signal is set just outside its DBC range (CRC and counter valid)",
    "wrong_dlc": "the frame is sent with `dlc` bytes",
    "flood": "each frame the node sends is followed by `rate` frames of an unknown ID with random data",
}
SIGNAL_KINDS = {"stuck", "offset", "gain", "out_of_range"}
CLASSIC_LENGTHS = tuple(range(9))  # a classic CAN frame's data lengths [bytes]
FD_LENGTHS = (*CLASSIC_LENGTHS, 12, 16, 20, 24, 32, 48, 64)  # a CAN FD frame's (DLC 9-15 code 12-64)
SIDES = {"PLANT": "plant", "TCU": "tcu"}  # DBC node -> side
_ALIASES = {"p": "probability", "delay": "delay_s", "id": "frame_id", "start": "start_s", "end": "end_s"}


class FaultError(InputError):
    """A fault specification is malformed or names something the DBC does not have."""


@dataclass(frozen=True)
class FaultSpec:
    kind: str
    target: str | None = None  # MESSAGE or MESSAGE.Signal
    start_s: float = 0.0
    end_s: float = math.inf
    probability: float = 1.0
    delay_s: float = 0.0
    value: float = 0.0
    dlc: int = 7
    rate: int = 10
    frame_id: int = 0x5A5
    side: str | None = None  # "plant" | "tcu"; None: the target's DBC sender (see :func:`fault_side`)
    origin: str = field(default="fault", compare=False)  # where it was given, for error messages

    @property
    def message(self) -> str | None:
        return None if self.target is None else self.target.split(".", 1)[0]

    @property
    def signal(self) -> str | None:
        return self.target.split(".", 1)[1] if self.target and "." in self.target else None

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s

    def describe(self) -> str:
        where = f":{self.target}" if self.target else ""
        end = "" if math.isinf(self.end_s) else f"{self.end_s:g}"
        return f"{self.kind}{where}@{self.start_s:g}-{end}"

    def as_option(self) -> str:
        """The ``--fault`` text that gives this specification back (e.g. to pass it on to ecu-stub)."""
        keys = [f"{f.name}={getattr(self, f.name)!r}" for f in fields(self)
                if f.name not in ("kind", "target", "start_s", "end_s", "origin")
                and getattr(self, f.name) != f.default]
        return ",".join([self.describe(), *(k.replace("'", "") for k in keys)])


def _number(key: str, raw: Any, where: str) -> float:
    if isinstance(raw, bool):
        raise FaultError(f"{where}: {key} must be a number, got {raw!r}")
    try:
        value = float(int(raw, 0)) if isinstance(raw, str) and raw.lower().startswith("0x") else float(raw)
    except (TypeError, ValueError):
        raise FaultError(f"{where}: {key} must be a number, got {raw!r}") from None
    if math.isnan(value) or (math.isinf(value) and key != "end_s"):
        raise FaultError(f"{where}: {key} must be finite, got {raw!r}")
    return value


def fault_from_mapping(table: Mapping[str, Any], where: str = "fault") -> FaultSpec:
    """A :class:`FaultSpec` from a TOML table or parsed command-line keys; checks types and ranges."""
    known = {f.name for f in fields(FaultSpec)} - {"origin"}
    items = {_ALIASES.get(k, k): v for k, v in table.items()}
    unknown = sorted(set(items) - known)
    if unknown:
        raise FaultError(f"{where}: unknown key {unknown[0]!r} (known: {', '.join(sorted(known))})")
    kind = items.get("kind")
    if kind not in KINDS:
        raise FaultError(f"{where}: kind must be one of {', '.join(KINDS)}, got {kind!r}")
    target = items.get("target")
    if target is not None and (not isinstance(target, str) or not target):
        raise FaultError(f"{where}: target must be MESSAGE or MESSAGE.Signal, got {target!r}")
    side = items.get("side")
    if side is not None and side not in SIDES.values():
        raise FaultError(f"{where}: side must be one of {', '.join(SIDES.values())}, got {side!r}")
    values: dict[str, Any] = {"kind": kind, "target": target, "side": side, "origin": where}
    for key in ("start_s", "end_s", "probability", "delay_s", "value"):
        if key in items:
            values[key] = _number(key, items[key], where)
    for key in ("dlc", "rate", "frame_id"):
        if key in items:
            number = _number(key, items[key], where)
            if number != int(number):
                raise FaultError(f"{where}: {key} must be a whole number, got {items[key]!r}")
            values[key] = int(number)
    spec = FaultSpec(**values)
    if not 0.0 <= spec.probability <= 1.0:
        raise FaultError(f"{where}: probability must be within [0, 1], got {spec.probability:g}")
    if not 0.0 <= spec.start_s < spec.end_s:
        raise FaultError(f"{where}: window must satisfy 0 <= start_s < end_s, got {spec.start_s:g}-{spec.end_s:g}")
    if spec.delay_s < 0.0:
        raise FaultError(f"{where}: delay_s must not be negative")
    if spec.dlc not in FD_LENGTHS:
        raise FaultError(f"{where}: dlc must be a frame length: 0-8, or on a CAN FD message 12, 16, 20, 24, 32, 48 "
                         f"or 64, got {spec.dlc}")
    if not 1 <= spec.rate <= 1000:
        raise FaultError(f"{where}: rate must be within 1-1000, got {spec.rate}")
    if not 0 <= spec.frame_id <= 0x7FF:
        raise FaultError(f"{where}: frame_id must be an 11-bit ID, got {spec.frame_id:#x}")
    if kind == "flood":
        if target is not None:
            raise FaultError(f"{where}: flood takes no target (it adds frames of frame_id)")
    elif target is None:
        raise FaultError(f"{where}: {kind} needs a target MESSAGE{'.Signal' if kind in SIGNAL_KINDS else ''}")
    elif (kind in SIGNAL_KINDS) != ("." in target):
        raise FaultError(f"{where}: {kind} takes a {'MESSAGE.Signal' if kind in SIGNAL_KINDS else 'MESSAGE'} "
                         f"target, got {target!r}")
    if kind == "gain" and spec.value == 0.0:
        raise FaultError(f"{where}: gain needs a non-zero value, the factor (e.g. value=1.05); a signal held at 0 "
                         f"is stuck,value=0")
    return spec


def parse_fault(text: str) -> FaultSpec:
    """Parse ``KIND[:TARGET][@START-[END]][,key=value ...]`` (the ``--fault`` syntax)."""
    where = f"--fault {text!r}"
    head, *options = [part.strip() for part in text.split(",")]
    table: dict[str, Any] = {}
    if "@" in head:
        head, window = head.split("@", 1)
        start, sep, end = window.partition("-")
        if not sep:
            raise FaultError(f"{where}: the window is START-END or START- (seconds), got {window!r}")
        table["start_s"] = start or 0.0
        if end:
            table["end_s"] = end
    kind, _, target = head.partition(":")
    table["kind"] = kind.strip()
    if target:
        table["target"] = target.strip()
    for option in options:
        key, sep, value = option.partition("=")
        if not sep:
            raise FaultError(f"{where}: options are key=value, got {option!r}")
        table[key.strip()] = value.strip()
    return fault_from_mapping(table, where)


def fault_side(spec: FaultSpec, db: Database, sides: Mapping[str, str] | None = None) -> str:
    """Whose frames the fault changes: ``spec.side``, else the DBC sender of its message ("plant" for flood), else
    ``sides``' (by message, "plant" or "tcu": a binding's, the messages it sends and reads; another matrix's nodes
    are not PLANT and TCU)."""
    if spec.side is not None:
        return spec.side
    if spec.kind == "flood":
        return "plant"
    if spec.message is None:
        raise FaultError(f"{spec.origin}: {spec.kind} needs a target MESSAGE")
    senders = db.get_message_by_name(spec.message).senders
    side = SIDES.get(senders[0]) if senders else None
    if side is None and sides is not None:
        side = sides.get(spec.message)
    if side is None:
        raise FaultError(f"{spec.origin}: the DBC names no sender PLANT or TCU for {spec.message}: give side")
    return side


def check_faults(specs: Iterable[FaultSpec], db: Database, sides: Mapping[str, str] | None = None
                 ) -> dict[str, list[FaultSpec]]:
    """Check every specification against the DBC; the specifications by side ("plant", "tcu"; ``sides``: by
    message, where the DBC's senders do not say, see :func:`fault_side`)."""
    by_side: dict[str, list[FaultSpec]] = {"plant": [], "tcu": []}
    for spec in specs:
        check_against_dbc(spec, db, spec.origin)
        by_side[fault_side(spec, db, sides)].append(spec)
    return by_side


def check_against_dbc(spec: FaultSpec, db: Database, where: str = "fault") -> None:
    """The target must name a DBC message (and signal); a flood ID must not be one."""
    if spec.kind == "flood":
        if any(m.frame_id == spec.frame_id for m in db.messages):
            raise FaultError(f"{where}: flood frame_id {spec.frame_id:#x} is a DBC message; pick an unknown ID")
        return
    if spec.message is None:
        raise FaultError(f"{where}: {spec.kind} needs a target MESSAGE")
    try:
        message = db.get_message_by_name(spec.message)
    except KeyError:
        raise FaultError(f"{where}: message {spec.message!r} is not in the DBC") from None
    if spec.kind == "wrong_dlc" and spec.dlc not in CLASSIC_LENGTHS and not message.is_fd:
        raise FaultError(f"{where}: dlc {spec.dlc} is a CAN FD length, and {spec.message} is a classic CAN message "
                         f"(0-8)")
    if spec.signal is not None:
        try:
            signal = message.get_signal_by_name(spec.signal)
        except KeyError:
            raise FaultError(f"{where}: signal {spec.target!r} is not in the DBC") from None
        if spec.kind in ("stuck", "offset", "gain"):
            _check_encodable(spec, signal, where)


def _check_encodable(spec: FaultSpec, signal: Signal, where: str) -> None:
    """A ``stuck`` value the signal's bits cannot carry, an ``offset`` wider than all they carry, or a ``gain`` that
    takes the signal's smallest step beyond them is refused before the run (not found mid-run by the sender's
    encoder). An offset or gain that pushes some values out is
    handled per frame (:class:`~dsg_hil.protocol.faults.injector.FaultInjector`: counted, the frame unchanged)."""
    from ..ranges import raw_range, signal_range  # noqa: PLC0415 - cantools, loaded with the DBC

    lo, hi = raw_range(signal)
    minimum, maximum = signal_range(signal)
    unit = f" {signal.unit}" if signal.unit else ""
    if spec.kind == "stuck" and lo <= spec.value <= hi:
        return
    if spec.kind == "offset" and abs(spec.value) <= hi - lo:
        return
    if spec.kind == "gain":
        step = abs(signal.scale)
        if abs(spec.value) * step <= hi - lo:
            return
        raise FaultError(f"{where}: gain value {spec.value:g} cannot be encoded in {spec.target}: it takes one step "
                         f"of {step:g}{unit} to {abs(spec.value) * step:g}{unit}, beyond all its bits carry "
                         f"({lo:g} to {hi:g}{unit})")
    raise FaultError(f"{where}: {spec.kind} value {spec.value:g}{unit} cannot be encoded in {spec.target}: its "
                     f"bits carry {lo:g} to {hi:g}{unit} (DBC range {minimum:g} to {maximum:g}{unit})")
