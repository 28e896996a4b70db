"""A binding: which signal of a communication matrix (a DBC, or an ARXML through cantools) carries each quantity the
plant sends or reads, in which unit, and which messages the plant sends and reads, with their cycle times and
protection. One TOML file; the shipped ``dsg_hil.dbc`` comes with ``dsg_hil.binding.toml``.

The file::

    send = ["PLANT_ENGINE", ...]        # the messages the plant sends, in the order of a period's frames
    read = ["TCU_CMD", "TCU_STATUS"]    # the messages it reads

    [quantities]                        # quantity (SI, as :data:`QUANTITIES` names it) = "MESSAGE.Signal"
    omega_e = "PLANT_ENGINE.EngineSpeed"
    T_CL_pred = { signal = "TCU_STATUS.T_CL_Pred", unit = "degC" }   # the signal's unit, if the database lacks it

    [lockstep]                          # the lock-step handshake's signals (no quantity of the plant)
    tick = "SIM_SYNC.Tick"
    echo = "TCU_CMD.SyncEcho"

    [messages.TCU_CMD]                  # optional, per message: the database's cycle time overridden, protection
    cycle_time_ms = 10
    protection = { profile = "dsg-hil" }   # none, dsg-hil, P01, P02, P05, P11 (:mod:`.profiles`)

A quantity's value is the signal's physical value (the database's scaling) in the signal's unit, converted to the
quantity's unit by :data:`UNITS` (r/min to rad/s, MPa to Pa, % to a fraction, km/h to m/s, K to degC ...).
:func:`load_binding` checks the file and the database together and gives a :class:`Binding`, plain tables the
plant's compiled I/O (:class:`dsg_hil.sim.plant_io.PlantIO`) is built from. Bad input: :class:`BindingError`,
one line naming the file and the key.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from cantools.database.can import Database

from ..common.units import CV
from .codec import ProtocolError, load_dbc
from .e2e import ProtectionError
from .profiles import protection_for

__all__ = ["DEFAULT_BINDING", "QUANTITIES", "UNITS", "Binding", "BindingError", "Quantity", "conversion",
           "load_binding"]

DEFAULT_BINDING = resources.files("dsg_hil") / "data" / "dsg_hil.binding.toml"  # of dbc/dsg_hil.binding.toml


class BindingError(ProtocolError):
    """The binding file is missing, unreadable, or does not fit its database."""


@dataclass(frozen=True)
class Quantity:
    """A quantity of the plant on the bus: its unit (SI; degC for temperatures, as the plant has them), whether the
    plant sends or reads it, and whether the plant needs it mapped (``required``)."""

    unit: str
    direction: str  # "send" or "read"
    required: bool = False
    doc: str = ""


def _q(unit: str, doc: str, direction: str = "send", required: bool = False) -> Quantity:
    return Quantity(unit, direction, required, doc)


# Every quantity a binding may map: the plant's outputs (PlantOutputs' attributes), the driver's input (DriverInput's),
# the truth, and what it reads of the TCU's frames. The plant sends the ones mapped; it needs the commands.
QUANTITIES: dict[str, Quantity] = {
    "omega_e": _q("rad/s", "engine speed"),
    "M_e": _q("Nm", "engine torque"),
    "omega_in": _q("rad/s", "clutch input (drum) speed"),
    "omega_CL": _q("rad/s", "clutch CL output speed"),
    "omega_CH": _q("rad/s", "clutch CH output speed"),
    "omega_out": _q("rad/s", "transmission output speed"),
    "v": _q("m/s", "vehicle speed"),
    "a_x": _q("m/s2", "longitudinal acceleration (body + g sin(grade))"),
    "P_CL": _q("Pa", "clutch CL pressure"),
    "P_CH": _q("Pa", "clutch CH pressure"),
    "T_oil_CL": _q("degC", "clutch CL oil temperature"),
    "T_oil_CH": _q("degC", "clutch CH oil temperature"),
    "T_sump": _q("degC", "sump temperature"),
    "T_radiator_out": _q("degC", "radiator outlet temperature"),
    "creep_request": _q("1", "driver: creep requested (0/1)"),
    "brake": _q("1", "driver: brake pedal, a fraction"),
    "desired_speed_mps": _q("m/s", "driver: desired creep speed"),
    "T_CL": _q("degC", "truth: clutch CL plate temperature"),
    "mu_CL": _q("1", "truth: clutch CL friction coefficient"),
    "M_CL": _q("Nm", "truth: clutch CL torque"),
    "Q_CL": _q("W", "truth: clutch CL heat flux"),
    "T_CH": _q("degC", "truth: clutch CH plate temperature"),
    "mu_CH": _q("1", "truth: clutch CH friction coefficient"),
    "M_CH": _q("Nm", "truth: clutch CH torque"),
    "Q_CH": _q("W", "truth: clutch CH heat flux"),
    "Q_diss_CL": _q("W", "truth: clutch CL heat dissipated to the oil"),
    "Q_diss_CH": _q("W", "truth: clutch CH heat dissipated to the oil"),
    "P_CL_cmd": _q("Pa", "TCU: commanded pressure CL", "read", True),
    "P_CH_cmd": _q("Pa", "TCU: commanded pressure CH", "read", True),
    "decel_request": _q("m/s2", "TCU: deceleration asked of the brakes", "read"),
    "tcu_state": _q("1", "TCU: state", "read", True),
    "active_clutch": _q("1", "TCU: active clutch", "read", True),
    "brake_request": _q("1", "TCU: brake request (0/1)", "read"),
    "T_CL_pred": _q("degC", "TCU: predicted plate temperature CL", "read", True),
    "T_CH_pred": _q("degC", "TCU: predicted plate temperature CH", "read", True),
    "fault_bits": _q("1", "TCU: fault bits", "read"),
}
COMMAND = ("P_CL_cmd", "P_CH_cmd", "decel_request")  # in the message that answers a lock-step tick (the echo's)
STATUS = ("tcu_state", "active_clutch", "brake_request", "T_CL_pred", "T_CH_pred", "fault_bits")  # in one message

# unit as a database writes it -> (dimension, factor, offset): the value in the dimension's base unit (the
# quantities' units) is value * factor + offset. The factors are CV's, to the last bit.
UNITS: dict[str, tuple[str, float, float]] = {
    "rad/s": ("angular speed", 1.0, 0.0), "rpm": ("angular speed", CV.RPM_TO_RAD_S, 0.0),
    "r/min": ("angular speed", CV.RPM_TO_RAD_S, 0.0), "1/min": ("angular speed", CV.RPM_TO_RAD_S, 0.0),
    "Pa": ("pressure", 1.0, 0.0), "kPa": ("pressure", 1e3, 0.0), "bar": ("pressure", 1e5, 0.0),
    "MPa": ("pressure", CV.MPA_TO_PA, 0.0),
    "m/s": ("speed", 1.0, 0.0), "km/h": ("speed", 1.0 / 3.6, 0.0),
    "m/s2": ("acceleration", 1.0, 0.0), "m/s^2": ("acceleration", 1.0, 0.0),
    "Nm": ("torque", 1.0, 0.0), "N m": ("torque", 1.0, 0.0), "N.m": ("torque", 1.0, 0.0),
    "W": ("power", 1.0, 0.0), "kW": ("power", CV.KW_TO_W, 0.0),
    "degC": ("temperature", 1.0, 0.0), "°C": ("temperature", 1.0, 0.0), "K": ("temperature", 1.0, -273.15),
    "1": ("ratio", 1.0, 0.0), "-": ("ratio", 1.0, 0.0), "": ("ratio", 1.0, 0.0),
    "%": ("ratio", CV.PERCENT_TO_FRACTION, 0.0),
}


def conversion(signal_unit: str, quantity_unit: str) -> tuple[float, float] | None:
    """(factor, offset): a value in ``signal_unit`` times factor plus offset is the value in ``quantity_unit`` (a
    base unit of :data:`UNITS`); None if they do not convert (another dimension, or a unit not in the table)."""
    signal, quantity = UNITS.get(signal_unit.strip()), UNITS.get(quantity_unit)
    if signal is None or quantity is None or signal[0] != quantity[0]:
        return None
    assert quantity[1:] == (1.0, 0.0), quantity_unit  # the quantities' units are the base units
    return signal[1], signal[2]


@dataclass(frozen=True)
class Binding:
    """A checked binding: plain tables (:class:`dsg_hil.sim.plant_io.PlantIO` is built from them).

    * ``tx``/``rx``: by message the plant sends/reads (``send``'s order), its signals used, in the database's order;
    * ``signals``: (message, signal) -> (quantity, factor); ``offsets``: the ones with an offset (K to degC);
    * ``sync``: (message, signal) of the lock-step tick; ``echo``: of the TCU's echo of it;
    * ``cycle_times_ms``: the overridden cycle times; ``protection``: by message, its protection table;
    * ``units``: by quantity mapped, the signal's unit.
    """

    path: str
    db: Database = field(repr=False)
    tx: dict[str, tuple[str, ...]]
    rx: dict[str, tuple[str, ...]]
    signals: dict[tuple[str, str], tuple[str, float]]
    offsets: dict[tuple[str, str], float]
    sync: tuple[str, str]
    echo: tuple[str, str]
    cycle_times_ms: dict[str, int]
    protection: dict[str, dict[str, object]]
    units: dict[str, str]

    @property
    def uses(self) -> dict[str, tuple[str, ...]]:
        """Every message the plant's codec uses: the ones sent, the tick's, the ones read."""
        return {**self.tx, self.sync[0]: (self.sync[1],), **self.rx}


def _fail(path: str, text: str) -> BindingError:
    return BindingError(f"{path}: {text}")


def _signal_ref(path: str, key: str, ref: object, db: Database) -> tuple[str, str]:
    if not isinstance(ref, str) or ref.count(".") != 1:
        raise _fail(path, f"{key} must be \"MESSAGE.Signal\", got {ref!r}")
    message, signal = ref.split(".")
    try:
        found = db.get_message_by_name(message)
    except KeyError:
        raise _fail(path, f"{key}: message {message} is not in the database") from None
    try:
        found.get_signal_by_name(signal)
    except KeyError:
        raise _fail(path, f"{key}: signal {message}.{signal} is not in the database") from None
    return message, signal


def _names(path: str, data: Mapping[str, Any], key: str, db: Database) -> list[str]:
    names = data.get(key)
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names) or len(set(names)) != len(names):
        raise _fail(path, f"{key} must be a list of message names, each once, got {names!r}")
    for name in names:
        try:
            db.get_message_by_name(name)
        except KeyError:
            raise _fail(path, f"{key}: message {name} is not in the database") from None
    return names


def read_toml(path: str | Path | None) -> tuple[str, dict[str, Any]]:
    """(the name to report, the TOML's tables) of a binding file (None: the shipped one)."""
    name = str(path) if path is not None else str(DEFAULT_BINDING)
    try:
        text = DEFAULT_BINDING.read_text(encoding="utf-8") if path is None else Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise _fail(name, "binding file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise _fail(name, f"cannot read the binding ({exc})") from None
    try:
        return name, tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise _fail(name, f"not TOML ({exc})") from None


def load_binding(path: str | Path | None = None, db: Database | None = None,
                 dbc: str | Path | None = None) -> Binding:
    """The binding in ``path`` (None: the shipped one) on ``db`` (else the database ``dbc``, None: the shipped
    DBC), checked: every message and signal in the database, each unit convertible, the quantities the plant needs
    mapped, the command quantities in the echo's message, the status ones in one message. The database's cycle
    times are overridden in ``db`` where the binding says so. :class:`BindingError` otherwise."""
    name, data = read_toml(path)
    db = db if db is not None else load_dbc(dbc)
    unknown = sorted(set(data) - {"send", "read", "quantities", "lockstep", "messages"})
    if unknown:
        raise _fail(name, f"unknown key {unknown[0]!r} (send, read, quantities, lockstep, messages)")
    send, read = _names(name, data, "send", db), _names(name, data, "read", db)
    both = sorted(set(send) & set(read))
    if both:
        raise _fail(name, f"message {both[0]} is both sent and read")
    lockstep = data.get("lockstep")
    if not isinstance(lockstep, dict) or set(lockstep) != {"tick", "echo"}:
        raise _fail(name, "lockstep must be a table with tick and echo (\"MESSAGE.Signal\" each)")
    sync = _signal_ref(name, "lockstep.tick", lockstep["tick"], db)
    echo = _signal_ref(name, "lockstep.echo", lockstep["echo"], db)
    if sync[0] in send or sync[0] in read:
        raise _fail(name, f"lockstep.tick: message {sync[0]} is the tick's alone (not in send or read)")
    if echo[0] not in read:
        raise _fail(name, f"lockstep.echo: message {echo[0]} is not one the plant reads")
    quantities = data.get("quantities")
    if not isinstance(quantities, dict):
        raise _fail(name, "quantities must be a table: quantity = \"MESSAGE.Signal\"")
    mapped: dict[tuple[str, str], tuple[str, float, float]] = {}
    units: dict[str, str] = {}
    for quantity, entry in quantities.items():
        key = f"quantities.{quantity}"
        spec = QUANTITIES.get(quantity)
        if spec is None:
            raise _fail(name, f"{key}: not a quantity of the plant ({', '.join(QUANTITIES)})")
        unit = None
        if isinstance(entry, dict):
            extra = sorted(set(entry) - {"signal", "unit"})
            if extra or "signal" not in entry:
                raise _fail(name, f"{key} must be \"MESSAGE.Signal\" or {{signal = ..., unit = ...}}")
            entry, unit = entry["signal"], entry.get("unit")
            if unit is not None and not isinstance(unit, str):
                raise _fail(name, f"{key}.unit must be a string, got {unit!r}")
        message, signal = _signal_ref(name, key, entry, db)
        if (message, signal) in mapped or (message, signal) in (sync, echo):
            raise _fail(name, f"{key}: signal {message}.{signal} carries another quantity already")
        if message not in (send if spec.direction == "send" else read):
            raise _fail(name, f"{key}: message {message} is not in {spec.direction} (the plant "
                              f"{'sends' if spec.direction == 'send' else 'reads'} {quantity})")
        unit = unit if unit is not None else db.get_message_by_name(message).get_signal_by_name(signal).unit or ""
        converted = conversion(unit, spec.unit)
        if converted is None:
            raise _fail(name, f"{key}: unit {unit!r} of {message}.{signal} does not convert to {spec.unit}")
        mapped[message, signal] = (quantity, *converted)
        units[quantity] = unit
    missing = [q for q, spec in QUANTITIES.items() if spec.required and q not in units]
    if missing:
        raise _fail(name, f"quantities: {missing[0]} is not mapped (the plant needs it)")
    where = {quantity: message for (message, _), (quantity, _, _) in mapped.items()}
    for group, carrier in ((COMMAND, echo[0]), (STATUS, where["tcu_state"])):
        for quantity in group:
            if quantity in where and where[quantity] != carrier:
                raise _fail(name, f"quantities.{quantity}: must be in {carrier}, with "
                                  f"{'the lock-step echo' if group is COMMAND else 'tcu_state'}")
    cycle_times, protection = _messages(name, data.get("messages", {}), [*send, sync[0], *read], db)
    for message_name in (*send, sync[0], *read):
        found = db.get_message_by_name(message_name)
        if message_name in cycle_times:
            found.cycle_time = cycle_times[message_name]
        elif found.cycle_time is None or found.cycle_time <= 0:
            raise _fail(name, f"message {message_name} has no cycle time in the database: give "
                              f"messages.{message_name}.cycle_time_ms")

    def used(message_name: str) -> tuple[str, ...]:
        extra = {s for m, s in (sync, echo) if m == message_name}
        return tuple(s.name for s in db.get_message_by_name(message_name).signals
                     if (message_name, s.name) in mapped or s.name in extra)

    tx, rx = {m: used(m) for m in send}, {m: used(m) for m in read}
    order = [(m, s) for table in (tx, rx) for m, signals in table.items() for s in signals if (m, s) in mapped]
    return Binding(name, db, tx, rx, {key: mapped[key][:2] for key in order},
                   {key: mapped[key][2] for key in order if mapped[key][2] != 0.0}, sync, echo, cycle_times,
                   protection, units)


def _messages(path: str, table: object, known: list[str], db: Database) -> tuple[dict[str, int],
                                                                                    dict[str, dict[str, object]]]:
    if not isinstance(table, dict):
        raise _fail(path, "messages must be a table of tables, by message name")
    cycle_times: dict[str, int] = {}
    protection: dict[str, dict[str, object]] = {}
    for message, entry in table.items():
        key = f"messages.{message}"
        if message not in known:
            raise _fail(path, f"{key}: not a message the plant sends or reads")
        if not isinstance(entry, dict) or set(entry) - {"cycle_time_ms", "protection"}:
            raise _fail(path, f"{key} may give cycle_time_ms and protection only")
        if "cycle_time_ms" in entry:
            value = entry["cycle_time_ms"]
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                raise _fail(path, f"{key}.cycle_time_ms must be a whole number of ms above 0, got {value!r}")
            cycle_times[message] = value
        if "protection" in entry:
            if not isinstance(entry["protection"], dict):
                raise _fail(path, f"{key}.protection must be a table with a profile key")
            protection[message] = dict(entry["protection"])
            try:
                protection_for(db.get_message_by_name(message), protection[message])
            except ProtectionError as exc:
                raise _fail(path, f"{key}.protection: {exc}") from None
    return cycle_times, protection
