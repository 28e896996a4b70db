"""The TCU's side of a binding (:mod:`dsg_hil.protocol.binding`): which signal of the communication matrix carries
each quantity ecu-stub reads or sends, and the one conversion between that signal's unit and the unit the TCU
computes in. The binding is the plant's file (its ``send`` messages are the ones the TCU reads, its ``read`` ones
the TCU sends); the same pair of files moves both ends to another matrix.

The TCU names its quantities as the binding does (SI there: rad/s, Pa, m/s, a fraction, degC); its controller
computes in r/min, MPa and % (:class:`~ecu_stub.controller.TcuInputs`, :class:`~ecu_stub.controller.TcuOutputs`).
:data:`INPUTS` and :data:`OUTPUTS` give each quantity's unit in the TCU, and a signal's value converts to it (and
back) by ``value * k + c`` with k and c composed once from the two units' entries in
:data:`dsg_hil.protocol.binding.UNITS` (:func:`edge`): on the shipped matrix, whose signals are in the TCU's units,
k is 1 and the value is taken as it is, so the shipped frames stay the same bit for bit.

A quantity of :data:`INPUTS` the binding leaves unmapped: :class:`~dsg_hil.protocol.binding.BindingError` naming
the file and the quantity (ecu-stub exits 2). One of :data:`OUTPUTS` unmapped is not sent (the plant does not read
it; :func:`~dsg_hil.protocol.binding.check_binding` insists on the ones the plant needs).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from cantools.database.can import Database

from dsg_hil.protocol.binding import (QUANTITIES, UNITS, Binding, BindingError, load_binding, shipped_binding,
                                      shipped_numbers)
from dsg_hil.protocol.validity import TIMEOUT_CYCLES

from .sensor_checks import MatrixSteps

if TYPE_CHECKING:
    from dsg_hil.protocol import Codec

__all__ = ["CLUTCH_VALUES", "INPUTS", "OUTPUTS", "SHIPPED", "STATE_VALUES", "TcuIO", "edge", "from_binding", "tcu_io"]

# the quantities the TCU reads, in the order :meth:`ecu_stub.runner.TcuRunner.inputs` unpacks them: its unit there
INPUTS: dict[str, str] = {
    "omega_e": "rpm", "omega_in": "rpm", "omega_CL": "rpm", "omega_CH": "rpm", "v": "m/s", "a_x": "m/s2",
    "P_CL": "MPa", "P_CH": "MPa", "T_oil_CL": "degC", "T_oil_CH": "degC", "T_sump": "degC", "creep_request": "1",
    "brake": "%", "desired_speed_mps": "m/s",
}
# the quantities the TCU sends: the expression of its value in the TCU's unit, of the controller's outputs ``out``,
# ``states`` and ``clutches`` (the value tables of the status signals), and that unit
OUTPUTS: dict[str, tuple[str, str]] = {
    "tcu_state": ("states[out.state]", "1"), "active_clutch": ("clutches[out.active_clutch]", "1"),
    "brake_request": ("float(out.brake_request)", "1"), "T_CL_pred": ("out.T_CL_pred_c", "degC"),
    "T_CH_pred": ("out.T_CH_pred_c", "degC"), "fault_bits": ("out.fault_bits", "1"),
    "P_CL_cmd": ("out.P_CL_cmd_mpa", "MPa"), "P_CH_cmd": ("out.P_CH_cmd_mpa", "MPa"),
    "decel_request": ("out.decel_request_mps2", "m/s2"),
}


def edge(signal_unit: str, tcu_unit: str) -> tuple[float, float]:
    """(k, c): a value in ``signal_unit`` times k plus c is the value in ``tcu_unit`` (both of one dimension of
    :data:`~dsg_hil.protocol.binding.UNITS`); (1.0, 0.0) exactly where the two convert alike. (``edge(tcu_unit,
    signal_unit)``: the other way.)"""
    _, f_signal, o_signal = UNITS[signal_unit.strip()]
    _, f_tcu, o_tcu = UNITS[tcu_unit]
    if (f_signal, o_signal) == (f_tcu, o_tcu):
        return 1.0, 0.0
    return f_signal / f_tcu, (o_signal - o_tcu) / f_tcu


class TcuIO:
    """The TCU's messages and signals on one matrix, from a checked :class:`~dsg_hil.protocol.binding.Binding`:

    * ``rx``: by message the TCU reads (the plant's that carry an input of :data:`INPUTS`, then the tick's), the
      signals it reads; ``required``: those messages but the tick's (a control step needs them all valid);
      ``inputs``: per quantity of :data:`INPUTS`, in its order, (index in ``required``, signal, k, c);
    * ``tx``: by message the TCU sends (the echo's, the command, last: it completes a lock-step answer), its
      signals; ``tx_values``: by message, by signal, the expression of its value (:data:`OUTPUTS`, converted);
    * ``names``: (tick message, tick signal, command message, echo signal, status message), as
      :class:`dsg_hil.protocol.lockstep.LockstepResponder` takes them; ``where``: by quantity mapped, its
      (message, signal); ``steps``: by quantity mapped, its signal's step in the TCU's unit;
    * ``protection``, ``timeouts``: the codec's (:class:`dsg_hil.protocol.Codec`), by message;
    * ``state_values``, ``clutch_values``: the number the matrix sends for each state and active clutch of the
      controller (its value table's, where the binding names them: ``values``; else the shipped DBC's);
    * ``matrix_steps``: the steps and times the plausibility checks and the controller take from the matrix
      (:class:`~ecu_stub.sensor_checks.MatrixSteps`: the speed frames' receive timeout, the oil frame's refresh,
      the speeds' steps in the TCU's units).
    """

    def __init__(self, binding: Binding) -> None:
        db: Database = binding.db
        self.path = binding.path
        where: dict[str, tuple[str, str]] = {quantity: key for key, (quantity, _) in binding.signals.items()}
        self.where = where
        missing = [quantity for quantity in INPUTS if quantity not in where]
        if missing:
            raise BindingError(f"{binding.path}: quantities.{missing[0]}: not mapped, and ecu-stub reads it "
                               f"({QUANTITIES[missing[0]].doc})")
        self.steps: dict[str, float] = {}
        conversions: dict[str, tuple[float, float]] = {}
        units = {**INPUTS, **{quantity: unit for quantity, (_, unit) in OUTPUTS.items()}}
        for quantity, (message, signal) in where.items():
            if quantity not in units:
                continue
            k, c = conversions[quantity] = edge(binding.units[quantity], units[quantity])
            scale = float(db.get_message_by_name(message).get_signal_by_name(signal).scale)
            self.steps[quantity] = scale if k == 1.0 else abs(scale * k)
        sync, tick = binding.sync
        command, echo = binding.echo
        status = where["tcu_state"][0] if "tcu_state" in where else command
        self.names: tuple[str, str, str, str, str] = (sync, tick, command, echo, status)
        read = {message for quantity, (message, _) in where.items() if quantity in INPUTS}
        self.required: tuple[str, ...] = tuple(m for m in binding.tx if m in read)  # (the database's send order)
        self.rx: dict[str, tuple[str, ...]] = {
            m: tuple(s.name for s in db.get_message_by_name(m).signals
                     if any(where.get(q) == (m, s.name) for q in INPUTS)) for m in self.required}
        self.rx[sync] = (tick,)
        self.inputs: tuple[tuple[int, str, float, float], ...] = tuple(
            (self.required.index(where[q][0]), where[q][1], *conversions[q]) for q in INPUTS)
        sent = [m for m in binding.rx if m != command] + [command]
        self.tx_values: dict[str, dict[str, str]] = {m: {} for m in sent}
        for quantity, (expression, unit) in OUTPUTS.items():
            if quantity in where:
                message, signal = where[quantity]
                k, c = edge(unit, binding.units[quantity])  # (the other way)
                if (k, c) != (1.0, 0.0):
                    expression = f"({expression}) * {k!r}" + (f" + {c!r}" if c != 0.0 else "")
                self.tx_values[message][signal] = expression
        self.tx_values[command][echo] = "echo"
        self.tx: dict[str, tuple[str, ...]] = {
            m: tuple(s.name for s in db.get_message_by_name(m).signals if s.name in self.tx_values[m]) for m in sent}
        self.protection: dict[str, dict[str, object]] = {
            m: p for m, p in binding.protection.items() if m in self.rx or m in self.tx}
        self.timeouts: dict[str, float] = {m: ms / 1000 for m, ms in binding.timeouts_ms.items() if m in self.rx}
        states, clutches = binding.values.get("tcu_state", {}), binding.values.get("active_clutch", {})
        self.state_values: dict[str, int] = {
            name: states.get(number, number) for name, number in shipped_numbers("tcu_state").items()}
        self.clutch_values: dict[str, int] = {
            name: clutches.get(number, number) for name, number in shipped_numbers("active_clutch").items()}
        self.matrix_steps = MatrixSteps(
            max(_timeout_ms(binding, where[q][0]) for q in ("v", "omega_CL", "omega_CH")) / 1000,
            max(_refresh_ms(db, where[q][0]) for q in ("T_oil_CL", "T_oil_CH", "T_sump")) / 1000,
            self.steps["v"], max(self.steps["omega_CL"], self.steps["omega_CH"]), self.steps["omega_in"])

    @property
    def uses(self) -> dict[str, tuple[str, ...]]:
        """Every message the TCU's codec uses, with its signals: the ones it reads, then the ones it sends."""
        return {**self.rx, **self.tx}

    def codec(self, db: Database, reference: bool = False) -> Codec:
        """The TCU's codec on ``db``: the messages and signals it uses, their protection and receive timeouts, of
        this matrix (``reference``: encoded and decoded through cantools, the codec's baseline)."""
        from dsg_hil.protocol import Codec  # noqa: PLC0415 - cantools' codec, built when a TCU is

        return Codec(db, self.uses, reference=reference, protection=self.protection, timeouts=self.timeouts)

    def step(self, quantity: str, default: float = 0.0) -> float:
        """The step of the signal that carries ``quantity``, in the TCU's unit (``default`` if unmapped)."""
        return self.steps.get(quantity, default)

    def renames(self, other: TcuIO) -> dict[str, str]:
        """By message ``other`` reads, the one this matrix carries its first input quantity in, where named
        otherwise (e.g. the diagnostic description's messages, the shipped DBC's, on this matrix)."""
        found: dict[str, str] = {}
        for quantity in INPUTS:
            found.setdefault(other.message(quantity), self.message(quantity))
        return {name: mine for name, mine in found.items() if name != mine}

    def message(self, quantity: str) -> str:
        """The message that carries ``quantity``."""
        return self.where[quantity][0]


def _timeout_ms(binding: Binding, message: str) -> float:
    """The TCU's receive timeout of ``message`` [ms]: the binding's, else :data:`~dsg_hil.protocol.validity.
    TIMEOUT_CYCLES` cycle times (the database's, or the binding's cycle_time_ms)."""
    given = binding.timeouts_ms.get(message)
    return float(given) if given is not None else TIMEOUT_CYCLES * _cycle_ms(binding.db, message)


def _cycle_ms(db: Database, message: str) -> int:
    """``message``'s cycle time [ms] (every message of a binding has one: checked when it is loaded)."""
    cycle = db.get_message_by_name(message).cycle_time
    assert cycle is not None and cycle > 0, f"{message}: no cycle time (the binding's check would have said)"
    return int(cycle)


def _refresh_ms(db: Database, message: str) -> float:
    """How often each value of ``message`` is sent anew [ms]: its cycle time, times its pages if multiplexed (the
    codec sends them in turn, :class:`dsg_hil.protocol.Codec`)."""
    found = db.get_message_by_name(message)
    pages = {page for signal in found.signals for page in signal.multiplexer_ids or ()}
    return float(_cycle_ms(db, message) * max(len(pages), 1))


def from_binding(binding: Binding) -> TcuIO:
    """The TCU's I/O of a loaded binding."""
    return TcuIO(binding)


def tcu_io(binding: str | Path | None = None, dbc: str | Path | None = None, db: Database | None = None) -> TcuIO:
    """The TCU's I/O of the binding file ``binding`` (None: the shipped one) on the database ``db`` (else the file
    ``dbc``; None: the shipped DBC); :class:`~dsg_hil.protocol.binding.BindingError` naming the file otherwise."""
    return TcuIO(load_binding(binding, db=db, dbc=dbc))


SHIPPED = TcuIO(shipped_binding())  # the shipped DBC with its binding


def _numbers(quantity: str) -> dict[str, int]:
    """The value table (VAL_) of ``quantity``'s signal in the shipped DBC: {name: number}."""
    message, signal = SHIPPED.where[quantity]
    table = shipped_binding().db.get_message_by_name(message).get_signal_by_name(signal).choices
    return {str(name): int(value) for value, name in (table or {}).items()}


# the numbers of the TCU's states and active clutch: the quantities tcu_state and active_clutch are these numbers
# (ecu-stub's diagnostic description's too); a matrix numbering them otherwise names them in its binding (values:
# TcuIO.state_values, clutch_values), and both ends send and read its numbers
STATE_VALUES: dict[str, int] = _numbers("tcu_state")
CLUTCH_VALUES: dict[str, int] = _numbers("active_clutch")
