"""A binding: which signal of a communication matrix (a DBC, or an ARXML through cantools) carries each quantity the
plant sends or reads, in which unit, and which messages the plant sends and reads, with their cycle times and
protection. One TOML file; the shipped ``dsg_hil.dbc`` comes with ``dsg_hil.binding.toml``.

The file::

    send = ["PLANT_ENGINE", ...]        # the messages the plant sends, in the order of a period's frames
    read = ["TCU_CMD", "TCU_STATUS"]    # the messages it reads

    [quantities]                        # quantity (SI, as :data:`QUANTITIES` names it) = "MESSAGE.Signal"
    omega_e = "PLANT_ENGINE.EngineSpeed"
    T_CL_pred = { signal = "TCU_STATUS.T_CL_Pred", unit = "degC" }   # the signal's unit, if the database lacks it
    tcu_state = { signal = "TCU_INFO.Mode", values = { IDLE = "Off", ENGAGE = "Launch", ... } }   # its value
                                        # table's names of the shipped DBC's values, where it numbers them otherwise

    [lockstep]                          # the lock-step handshake's signals (no quantity of the plant)
    tick = "SIM_SYNC.Tick"
    echo = "TCU_CMD.SyncEcho"

    [simulation]                        # optional: the simulation database's messages (SIM_SYNC, the truth)
    ids = { SIM_SYNC = 0x7E0, SIM_TRUTH_CL = 0x7A0 }   # added to the matrix on these IDs (:data:`SIM_DATABASE`)

    [messages.TCU_CMD]                  # optional, per message: the database's cycle time overridden, protection
    cycle_time_ms = 10
    timeout_ms = 30                     # its receiver's timeout, the plant's for a message it reads, the TCU's
                                        # (ecu-stub's) for one the plant sends (default 3 cycle times)
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
import copy
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import cantools
from cantools.database.can import Database, Signal

from ..common.units import CV
from .codec import ProtocolError, frame_length, load_dbc
from .e2e import ProtectionError
from .profiles import protection_for
from .ranges import signal_range

__all__ = ["DEFAULT_BINDING", "QUANTITIES", "SIM_DATABASE", "UNITS", "VALUED", "Binding", "BindingError", "Quantity",
           "add_simulation", "check_binding", "conversion", "load_binding", "shipped_binding", "shipped_numbers",
           "signal_fit"]

DEFAULT_BINDING = resources.files("dsg_hil") / "data" / "dsg_hil.binding.toml"  # of dbc/dsg_hil.binding.toml
# the simulation database (of dbc/dsg_hil_sim.dbc): the lock-step tick (SIM_SYNC) and the truth frames, which a
# binding's [simulation] table adds to a matrix that lacks them, on IDs of its choosing
SIM_DATABASE = resources.files("dsg_hil") / "data" / "dsg_hil_sim.dbc"


class BindingError(ProtocolError):
    """The binding file is missing, unreadable, or does not fit its database."""


@dataclass(frozen=True)
class Quantity:
    """A quantity of the plant on the bus: its unit (SI; degC for temperatures, as the plant has them), whether the
    plant sends or reads it, whether the plant needs it mapped (``required``), and the range and resolution (in
    its unit) a signal must carry it with: the values it takes in the scenarios dsg-hil is made for (the paper's
    creep, its faults), with the resolution the plant's and the TCU's numbers are compared at."""

    unit: str
    direction: str  # "send" or "read"
    lo: float
    hi: float
    resolution: float
    required: bool = False
    doc: str = ""


_RPM, _MPA = CV.RPM_TO_RAD_S, CV.MPA_TO_PA


def _q(unit: str, lo: float, hi: float, resolution: float, doc: str, direction: str = "send",
       required: bool = False) -> Quantity:
    return Quantity(unit, direction, lo, hi, resolution, required, doc)


# Every quantity a binding may map: the plant's outputs (PlantOutputs' attributes), the driver's input (DriverInput's),
# the truth, and what it reads of the TCU's frames. The plant sends the ones mapped; it needs the commands and the
# TCU's state. Ranges: engine and shaft speeds up to 8000 r/min, pressures to 1.5 MPa (the valves' maximum),
# plate temperatures to 350 degC (past the 300 degC limit of the paper's Section V.B), oil to 200 degC.
QUANTITIES: dict[str, Quantity] = {
    "omega_e": _q("rad/s", 0.0, 8000 * _RPM, 1 * _RPM, "engine speed"),
    "M_e": _q("Nm", -300.0, 600.0, 1.0, "engine torque"),
    "omega_in": _q("rad/s", -1000 * _RPM, 3000 * _RPM, 1 * _RPM, "clutch input (drum) speed"),
    "omega_CL": _q("rad/s", -1000 * _RPM, 3000 * _RPM, 1 * _RPM, "clutch CL output speed"),
    "omega_CH": _q("rad/s", -1000 * _RPM, 3000 * _RPM, 1 * _RPM, "clutch CH output speed"),
    "omega_out": _q("rad/s", -1000 * _RPM, 3000 * _RPM, 1 * _RPM, "transmission output speed"),
    "v": _q("m/s", -5.0, 25.0, 0.01, "vehicle speed"),
    "a_x": _q("m/s2", -10.0, 10.0, 0.01, "longitudinal acceleration (body + g sin(grade))"),
    "P_CL": _q("Pa", 0.0, 1.5 * _MPA, 0.001 * _MPA, "clutch CL pressure"),
    "P_CH": _q("Pa", 0.0, 1.5 * _MPA, 0.001 * _MPA, "clutch CH pressure"),
    "T_oil_CL": _q("degC", -40.0, 200.0, 0.5, "clutch CL oil temperature"),
    "T_oil_CH": _q("degC", -40.0, 200.0, 0.5, "clutch CH oil temperature"),
    "T_sump": _q("degC", -40.0, 200.0, 0.5, "sump temperature"),
    "T_radiator_out": _q("degC", -40.0, 200.0, 0.5, "radiator outlet temperature"),
    "creep_request": _q("1", 0.0, 1.0, 1.0, "driver: creep requested (0/1)"),
    "brake": _q("1", 0.0, 1.0, 0.01, "driver: brake pedal, a fraction"),
    "desired_speed_mps": _q("m/s", 0.0, 5.0, 0.01, "driver: desired creep speed"),
    "T_CL": _q("degC", -40.0, 350.0, 0.5, "truth: clutch CL plate temperature"),
    "mu_CL": _q("1", 0.0, 0.4, 0.001, "truth: clutch CL friction coefficient"),
    "M_CL": _q("Nm", -1000.0, 1000.0, 1.0, "truth: clutch CL torque"),
    "Q_CL": _q("W", 0.0, 40000.0, 50.0, "truth: clutch CL heat flux"),
    "T_CH": _q("degC", -40.0, 350.0, 0.5, "truth: clutch CH plate temperature"),
    "mu_CH": _q("1", 0.0, 0.4, 0.001, "truth: clutch CH friction coefficient"),
    "M_CH": _q("Nm", -1000.0, 1000.0, 1.0, "truth: clutch CH torque"),
    "Q_CH": _q("W", 0.0, 40000.0, 50.0, "truth: clutch CH heat flux"),
    "Q_diss_CL": _q("W", -20000.0, 20000.0, 10.0, "truth: clutch CL heat dissipated to the oil"),
    "Q_diss_CH": _q("W", -20000.0, 20000.0, 10.0, "truth: clutch CH heat dissipated to the oil"),
    "P_CL_cmd": _q("Pa", 0.0, 1.5 * _MPA, 0.001 * _MPA, "TCU: commanded pressure CL", "read", True),
    "P_CH_cmd": _q("Pa", 0.0, 1.5 * _MPA, 0.001 * _MPA, "TCU: commanded pressure CH", "read", True),
    "decel_request": _q("m/s2", 0.0, 10.0, 0.1, "TCU: deceleration asked of the brakes", "read"),
    "tcu_state": _q("1", 0.0, 5.0, 1.0, "TCU: state (the shipped DBC's VAL_ numbers; values: the matrix's names)",
                    "read", True),
    "active_clutch": _q("1", 0.0, 2.0, 1.0, "TCU: active clutch (the shipped DBC's VAL_ numbers; values: the "
                        "matrix's names)", "read", True),
    "brake_request": _q("1", 0.0, 1.0, 1.0, "TCU: brake request (0/1)", "read"),
    "T_CL_pred": _q("degC", -40.0, 350.0, 0.5, "TCU: predicted plate temperature CL", "read", True),
    "T_CH_pred": _q("degC", -40.0, 350.0, 0.5, "TCU: predicted plate temperature CH", "read", True),
    "fault_bits": _q("1", 0.0, 255.0, 1.0, "TCU: fault bits", "read"),
}
COMMAND = ("P_CL_cmd", "P_CH_cmd", "decel_request")  # in the message that answers a lock-step tick (the echo's)
STATUS = ("tcu_state", "active_clutch", "brake_request", "T_CL_pred", "T_CH_pred", "fault_bits")  # in one message
# numbered by the shipped DBC's value tables: an entry may give the matrix's names of those values (``values``)
VALUED = ("tcu_state", "active_clutch")

# unit as a database writes it -> (dimension, factor, offset): the value in the dimension's base unit (the
# quantities' units) is value * factor + offset. The factors are CV's, to the last bit.
UNITS: dict[str, tuple[str, float, float]] = {
    "rad/s": ("angular speed", 1.0, 0.0), "rpm": ("angular speed", CV.RPM_TO_RAD_S, 0.0),
    "r/min": ("angular speed", CV.RPM_TO_RAD_S, 0.0), "1/min": ("angular speed", CV.RPM_TO_RAD_S, 0.0),
    "Pa": ("pressure", 1.0, 0.0), "kPa": ("pressure", CV.KPA_TO_PA, 0.0), "bar": ("pressure", CV.BAR_TO_PA, 0.0),
    "MPa": ("pressure", CV.MPA_TO_PA, 0.0),
    "m/s": ("speed", 1.0, 0.0), "km/h": ("speed", CV.KMH_TO_MPS, 0.0),
    "m/s2": ("acceleration", 1.0, 0.0), "m/s^2": ("acceleration", 1.0, 0.0),
    "Nm": ("torque", 1.0, 0.0), "N m": ("torque", 1.0, 0.0), "N.m": ("torque", 1.0, 0.0),
    "W": ("power", 1.0, 0.0), "kW": ("power", CV.KW_TO_W, 0.0),
    "degC": ("temperature", 1.0, 0.0), "°C": ("temperature", 1.0, 0.0), "K": ("temperature", 1.0, -CV.ZERO_C_IN_K),
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
    * ``cycle_times_ms``: the overridden cycle times; ``timeouts_ms``: the receive timeouts given (the plant's of
      the messages it reads, the TCU's of the ones it sends);
      ``protection``: by message, its protection table;
    * ``units``: by quantity mapped, the signal's unit;
    * ``values``: by quantity of :data:`VALUED` whose entry gives ``values``, the number the matrix sends for
      each of the quantity's numbers (the shipped DBC's, :func:`shipped_numbers`); none: the same numbers.
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
    timeouts_ms: dict[str, int] = field(default_factory=dict)
    values: dict[str, dict[int, int]] = field(default_factory=dict)

    @property
    def uses(self) -> dict[str, tuple[str, ...]]:
        """Every message the plant's codec uses: the ones sent, the tick's, the ones read."""
        return {**self.tx, self.sync[0]: (self.sync[1],), **self.rx}

    @property
    def sides(self) -> dict[str, str]:
        """Whose frames each message is: "plant" for the ones it sends (the tick's too), "tcu" for the ones it reads
        (a fault's side where the database's senders are not PLANT and TCU)."""
        return {**dict.fromkeys((*self.tx, self.sync[0]), "plant"), **dict.fromkeys(self.rx, "tcu")}


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


def _names(path: str, data: Mapping[str, Any], key: str, db: Database, problems: list[str]) -> list[str]:
    """The messages of ``send`` or ``read`` that are in the database; a name that is not: a problem."""
    names = data.get(key)
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names) or len(set(names)) != len(names):
        raise _fail(path, f"{key} must be a list of message names, each once, got {names!r}")
    found = []
    for name in names:
        try:
            db.get_message_by_name(name)
        except KeyError:
            problems.append(f"{path}: {key}: message {name} is not in the database")
            continue
        found.append(name)
    return found


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
    DBC), checked (:func:`check_binding`); :class:`BindingError` with the first problem otherwise. The
    database's cycle times are overridden in ``db`` where the binding says so."""
    binding, problems = check_binding(path, db, dbc)
    if binding is None:
        raise BindingError(problems[0])
    return binding


@cache
def shipped_binding() -> Binding:
    """The shipped binding on the shipped DBC, loaded once (the plant's and the TCU's tables of it are made from
    this one): read it, do not change its database."""
    return load_binding()


def check_binding(path: str | Path | None = None, db: Database | None = None,
                  dbc: str | Path | None = None) -> tuple[Binding | None, list[str]]:
    """(the binding, []) or (None, every problem, one line each, naming the file and the key): a message or signal
    not in the database, a unit that does not convert, a signal whose range or resolution cannot carry its
    quantity's (:data:`QUANTITIES`), a quantity the plant needs unmapped, a message without a cycle time, a
    protection that does not fit its frame; the command quantities outside the echo's message, the status ones
    outside one message. A file that cannot be read as a binding at all: that one problem."""
    try:
        name, data = read_toml(path)
        db = db if db is not None else load_dbc(dbc)
    except ProtocolError as exc:
        return None, [str(exc)]
    problems: list[str] = []

    def problem(text: str) -> None:
        problems.append(f"{name}: {text}")

    try:
        unknown = sorted(set(data) - {"send", "read", "quantities", "lockstep", "messages", "simulation"})
        if unknown:
            raise _fail(name, f"unknown key {unknown[0]!r} (send, read, quantities, lockstep, messages, simulation)")
        if "simulation" in data:
            add_simulation(name, data["simulation"], db, problems)
        send, read = _names(name, data, "send", db, problems), _names(name, data, "read", db, problems)
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
    except BindingError as exc:
        return None, [*problems, str(exc)]
    mapped: dict[tuple[str, str], tuple[str, float, float]] = {}
    units: dict[str, str] = {}
    values: dict[str, dict[int, int]] = {}
    for quantity, entry in quantities.items():
        try:
            key, found = _quantity(name, quantity, entry, db, send, read, (sync, echo), mapped)
        except BindingError as exc:
            problems.append(str(exc))
            units[quantity] = "?"  # mapped, if badly: not "unmapped" too
            continue
        message, signal, unit, factor, offset = found
        mapped[message, signal] = (quantity, factor, offset)
        units[quantity] = unit
        dbc_signal = db.get_message_by_name(message).get_signal_by_name(signal)
        for text in signal_fit(quantity, dbc_signal, factor, offset):
            problem(f"{key}: {message}.{signal} carries {text}")
        if isinstance(entry, dict) and "values" in entry:
            try:
                values[quantity] = _values(name, key, quantity, entry["values"], f"{message}.{signal}", dbc_signal)
            except BindingError as exc:
                problems.append(str(exc))
    for quantity, spec in QUANTITIES.items():
        if spec.required and quantity not in units:
            problem(f"quantities: {quantity} is not mapped (the plant needs it)")
    where = {quantity: message for (message, _), (quantity, _, _) in mapped.items()}
    for group, carrier in ((COMMAND, echo[0]), (STATUS, where.get("tcu_state"))):
        for quantity in group:
            if carrier is not None and quantity in where and where[quantity] != carrier:
                problem(f"quantities.{quantity}: must be in {carrier}, with "
                        f"{'the lock-step echo' if group is COMMAND else 'tcu_state'}")
    cycle_times, protection, timeouts = _messages(name, data.get("messages", {}), [*send, sync[0], *read], sync[0], db,
                                                  problems)
    for message_name in (*send, sync[0], *read):
        carrier_message = db.get_message_by_name(message_name)
        if message_name not in cycle_times and (carrier_message.cycle_time is None or carrier_message.cycle_time <= 0):
            problem(f"message {message_name} has no cycle time in the database: give "
                    f"messages.{message_name}.cycle_time_ms")
        try:
            frame_length(carrier_message)
        except ProtocolError as exc:
            problem(str(exc))
        if message_name not in protection:
            try:
                protection_for(carrier_message)
            except ProtectionError as exc:
                problem(f"message {message_name}: {exc}: give messages.{message_name}.protection")
    if problems:
        return None, problems
    for message_name, cycle_time in cycle_times.items():
        db.get_message_by_name(message_name).cycle_time = cycle_time

    def used(message_name: str) -> tuple[str, ...]:
        extra = {s for m, s in (sync, echo) if m == message_name}
        return tuple(s.name for s in db.get_message_by_name(message_name).signals
                     if (message_name, s.name) in mapped or s.name in extra)

    tx, rx = {m: used(m) for m in send}, {m: used(m) for m in read}
    order = [(m, s) for table in (tx, rx) for m, signals in table.items() for s in signals if (m, s) in mapped]
    return Binding(name, db, tx, rx, {key: mapped[key][:2] for key in order},
                   {key: mapped[key][2] for key in order if mapped[key][2] != 0.0}, sync, echo, cycle_times,
                   protection, units, timeouts, values), []


def signal_fit(quantity: str, signal: Signal, factor: float, offset: float) -> list[str]:
    """Why ``signal`` (its value times ``factor`` plus ``offset`` in the quantity's unit) cannot carry ``quantity``:
    a range that ends inside the quantity's (:data:`QUANTITIES`), steps coarser than its resolution; [] if it can."""
    spec = QUANTITIES[quantity]
    lo, hi = (factor * v + offset for v in signal_range(signal))
    found = []
    if lo > spec.lo + 1e-9 * max(1.0, abs(spec.lo)) or hi < spec.hi - 1e-9 * max(1.0, abs(spec.hi)):
        found.append(f"{_num(lo)}..{_num(hi)} {spec.unit}, {quantity} needs {_num(spec.lo)}..{_num(spec.hi)} "
                     f"{spec.unit}")
    if abs(signal.scale * factor) > spec.resolution * (1 + 1e-9):
        found.append(f"steps of {_num(abs(signal.scale * factor))} {spec.unit}, {quantity} needs "
                     f"{_num(spec.resolution)} {spec.unit} or finer")
    return found


def add_simulation(path: str, table: object, db: Database, problems: list[str]) -> None:
    """The ``simulation`` table: each message of ``ids`` copied from :data:`SIM_DATABASE` into ``db`` on its ID.
    An ID the matrix uses (a message's, or its diagnostic request or response ID), one given twice, a message the
    matrix has already or the simulation database lacks: a problem each (appended to ``problems``; not added)."""
    if not isinstance(table, dict) or set(table) != {"ids"} or not isinstance(table["ids"], dict):
        raise _fail(path, "simulation must be a table with ids = { MESSAGE = ID, ... } (the simulation "
                          "database's messages to add, on these IDs)")
    simulation = cantools.database.load_string(SIM_DATABASE.read_text(encoding="utf-8"), "dbc", strict=True)
    assert isinstance(simulation, Database)
    taken = {m.frame_id: f"the ID of {m.name} in the matrix" for m in db.messages}
    attributes = db.dbc.attributes if db.dbc is not None else {}
    for attribute, what in (("DiagRequestId", "diagnostic request"), ("DiagResponseId", "diagnostic response")):
        if attribute in attributes:
            taken.setdefault(int(attributes[attribute].value), f"the matrix's {what} ID ({attribute})")
    added = []
    for message_name, frame_id in table["ids"].items():
        key = f"simulation.ids.{message_name}"
        try:
            message = copy.deepcopy(simulation.get_message_by_name(message_name))
        except KeyError:
            names = ", ".join(m.name for m in simulation.messages)
            problems.append(f"{path}: {key}: not a message of the simulation database ({names})")
            continue
        if isinstance(frame_id, bool) or not isinstance(frame_id, int) or not 0 <= frame_id <= 0x7FF:
            problems.append(f"{path}: {key} must be an 11-bit CAN ID (0x0-0x7FF), got {frame_id!r}")
            continue
        if any(m.name == message_name for m in db.messages):
            problems.append(f"{path}: {key}: the matrix has a message {message_name} already")
            continue
        if frame_id in taken:
            problems.append(f"{path}: {key}: 0x{frame_id:X} is {taken[frame_id]}")
            continue
        message.frame_id = frame_id
        taken[frame_id] = f"{message_name}'s too"
        added.append(message)
    if added:
        db.messages.extend(added)
        db.refresh()


def _num(value: float) -> str:
    return f"{value:.6g}"


def _quantity(path: str, quantity: str, entry: object, db: Database, send: list[str], read: list[str],
              lockstep: tuple[tuple[str, str], ...], mapped: Mapping[tuple[str, str], object]
              ) -> tuple[str, tuple[str, str, str, float, float]]:
    """(key, (message, signal, unit, factor, offset)) of one entry of ``quantities``; else :class:`BindingError`."""
    key = f"quantities.{quantity}"
    spec = QUANTITIES.get(quantity)
    if spec is None:
        raise _fail(path, f"{key}: not a quantity of the plant ({', '.join(QUANTITIES)})")
    unit: object = None
    if isinstance(entry, dict):
        allowed = {"signal", "unit", "values"} if quantity in VALUED else {"signal", "unit"}
        if set(entry) - allowed or "signal" not in entry:
            raise _fail(path, f"{key} must be \"MESSAGE.Signal\" or {{signal = ..., unit = ...}}"
                        + (" (values = {...}: the matrix's names of its values)" if quantity in VALUED else ""))
        table: dict = entry
        entry, unit = table["signal"], table.get("unit")
        if unit is not None and not isinstance(unit, str):
            raise _fail(path, f"{key}.unit must be a string, got {unit!r}")
    message, signal = _signal_ref(path, key, entry, db)
    if (message, signal) in mapped or (message, signal) in lockstep:
        raise _fail(path, f"{key}: signal {message}.{signal} carries another quantity already")
    if message not in (send if spec.direction == "send" else read):
        raise _fail(path, f"{key}: message {message} is not in {spec.direction} (the plant "
                          f"{'sends' if spec.direction == 'send' else 'reads'} {quantity})")
    unit = str(unit) if unit is not None else db.get_message_by_name(message).get_signal_by_name(signal).unit or ""
    converted = conversion(unit, spec.unit)
    if converted is None:
        raise _fail(path, f"{key}: unit {unit!r} of {message}.{signal} does not convert to {spec.unit}")
    return key, (message, signal, unit, *converted)


def shipped_numbers(quantity: str) -> dict[str, int]:
    """The numbers ``quantity`` (one of :data:`VALUED`) is, by name: the shipped DBC's value table of its signal."""
    shipped = shipped_binding()
    message, signal = next(key for key, (q, _) in shipped.signals.items() if q == quantity)
    choices: Mapping[int, object] = shipped.db.get_message_by_name(message).get_signal_by_name(signal).choices or {}
    return {str(name): int(number) for number, name in choices.items()}


def _values(path: str, key: str, quantity: str, table: object, where: str, signal: Signal) -> dict[int, int]:
    """``values`` of a :data:`VALUED` quantity's entry, {its name (the shipped DBC's): the matrix's name of it in
    the signal's value table}, as {the quantity's number: the matrix's number}; else :class:`BindingError`."""
    numbers = shipped_numbers(quantity)
    if not isinstance(table, dict) or set(table) != set(numbers) or not all(isinstance(v, str) for v in
                                                                           table.values()):
        raise _fail(path, f"{key}.values must give the matrix's name of each of {', '.join(numbers)}, got {table!r}")
    table_of: Mapping[int, object] = signal.choices or {}
    theirs = {str(name): int(number) for number, name in table_of.items()}
    for name, their_name in table.items():
        if their_name not in theirs:
            raise _fail(path, f"{key}.values.{name}: {their_name!r} is not in the value table of {where} "
                              f"({', '.join(theirs) or 'none'})")
    if len(set(table.values())) != len(table):
        raise _fail(path, f"{key}.values: two of the values have one name")
    return {numbers[name]: theirs[their_name] for name, their_name in table.items()}


def _messages(path: str, table: object, known: list[str], tick: str, db: Database, problems: list[str]
              ) -> tuple[dict[str, int], dict[str, dict[str, object]], dict[str, int]]:
    """The ``messages`` table: cycle times, protection and timeouts by message; its problems appended to
    ``problems``."""
    cycle_times: dict[str, int] = {}
    protection: dict[str, dict[str, object]] = {}
    timeouts: dict[str, int] = {}
    if not isinstance(table, dict):
        problems.append(f"{path}: messages must be a table of tables, by message name")
        return cycle_times, protection, timeouts
    for message, entry in table.items():
        key = f"messages.{message}"
        if message not in known:
            problems.append(f"{path}: {key}: not a message the plant sends or reads")
            continue
        if not isinstance(entry, dict) or set(entry) - {"cycle_time_ms", "timeout_ms", "protection"}:
            problems.append(f"{path}: {key} may give cycle_time_ms, timeout_ms and protection only")
            continue
        for field_name, values in (("cycle_time_ms", cycle_times), ("timeout_ms", timeouts)):
            if field_name not in entry:
                continue
            value = entry[field_name]
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                problems.append(f"{path}: {key}.{field_name} must be a whole number of ms above 0, got {value!r}")
            elif field_name == "timeout_ms" and message == tick:
                problems.append(f"{path}: {key}.timeout_ms: the lock-step tick has no receive timeout (the TCU "
                                f"waits for it)")
            else:
                values[message] = value
        if "protection" in entry:
            if not isinstance(entry["protection"], dict):
                problems.append(f"{path}: {key}.protection must be a table with a profile key")
                continue
            protection[message] = dict(entry["protection"])
            try:
                protection_for(db.get_message_by_name(message), protection[message])
            except ProtectionError as exc:
                problems.append(f"{path}: {key}.protection: {exc}")
    return cycle_times, protection, timeouts
