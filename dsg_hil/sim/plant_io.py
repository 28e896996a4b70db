"""The plant's side of the CAN contract: which messages it sends and reads, and one table, ``signals``, of what each
of their signals is in the plant's SI units, held by a :class:`PlantIO` built from a binding
(:mod:`dsg_hil.protocol.binding`; :data:`SHIPPED`: the shipped ``dsg_hil.dbc`` with ``dsg_hil.binding.toml``, whose
tables this module's names give: :data:`PLANT_TX`, :data:`PLANT_RX`, :data:`SIGNALS` ...). The table drives the
encoding of the plant's frames (:meth:`PlantIO.frame_encoder`, from :meth:`PlantIO.value_sources`;
:meth:`PlantIO.plant_signals` gives the values as dicts), the runner's reading of the TCU's command
(:meth:`PlantIO.commanded_pressures`) and status, and the bus-log reader (:mod:`dsg_hil.paper.report.log`): r/min,
MPa and % exist at this edge only (:class:`dsg_hil.common.units.CV`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, get_type_hints

from ..physics.plant import PlantOutputs
from ..protocol.binding import load_binding, shipped_binding
from ..protocol.codec import Codec
from .scenario import DriverInput

__all__ = ["LOCKSTEP", "PLANT_RX", "PLANT_TX", "PLANT_USES", "SHIPPED", "SIGNALS", "SYNC", "PlantIO", "commanded_decel",
           "commanded_pressures", "encoder_source", "frame_encoder", "plant_io", "plant_signals", "value_sources"]

_FLOATS = {source: {name for name, kind in get_type_hints(cls).items() if kind is float}  # the rest: float(...)
           for source, cls in (("out", PlantOutputs), ("driver", DriverInput))}
_DRIVER = frozenset(get_type_hints(DriverInput))  # quantities of the driver's input; the others: the plant's outputs
STATUS_KEYS = {"tcu_state": "State", "active_clutch": "ActiveClutch", "T_CL_pred": "T_CL_Pred",
               "T_CH_pred": "T_CH_Pred"}  # the status values the summary reads, by the shipped DBC's names
_READ = frozenset(("P_CL_cmd", "P_CH_cmd", "decel_request", "brake_request", "tcu_state", "active_clutch", "T_CL_pred",
                   "T_CH_pred"))  # the quantities the plant reads of the TCU's frames


def _to_dbc(quantity: str, factor: float, offset: float) -> str:
    """Source of a quantity of ``out`` (the plant's outputs) or ``driver`` in the signal's unit: less the offset,
    divided by the factor, written as a product with its reciprocal where the factor is below 1 (x 60/2pi for
    r/min, x 100 for %) and as a division where it is not (/ 1e6 for MPa): the constant that is exact where one is
    (the operations the plant always used, so its frames stay the same bit for bit)."""
    source = "driver" if quantity in _DRIVER else "out"
    value = f"{source}.{quantity}"
    if quantity not in _FLOATS[source]:
        value = f"float({value})"
    if offset != 0.0:
        value = f"({value} - {offset!r})"
    if factor == 1.0:
        return value
    return f"{value} * {1.0 / factor!r}" if factor < 1.0 else f"{value} / {factor!r}"


class PlantIO:
    """The plant's messages and signals, from plain tables (a binding's, :func:`plant_io`):

    * ``tx``/``rx``: by message sent/read, its signals used; ``sync``/``tick``: the lock-step tick's message and
      signal; ``command``/``echo``: the TCU's command message and its echo of the tick; ``status``: the message of
      the TCU's state;
    * ``signals``: (message, signal) -> (quantity, factor): the signal's value times ``factor`` (plus ``offsets``'
      entry, if any) is the quantity in SI (rad/s, Pa, m/s, N m, W, a fraction; degC as the plant has it). A
      quantity the plant sends is the attribute of that name of PlantOutputs (of DriverInput for the driver's);
    * ``values``: by quantity of the TCU's state (``tcu_state``, ``active_clutch``), the number the matrix sends
      for each of the quantity's numbers, where its value table numbers them otherwise (a binding's ``values``).
    """

    def __init__(self, tx: Mapping[str, Sequence[str]], rx: Mapping[str, Sequence[str]],
                 signals: Mapping[tuple[str, str], tuple[str, float]], sync: tuple[str, str], echo: tuple[str, str],
                 offsets: Mapping[tuple[str, str], float] | None = None,
                 values: Mapping[str, Mapping[int, int]] | None = None) -> None:
        self.tx: dict[str, tuple[str, ...]] = {m: tuple(s) for m, s in tx.items()}
        self.rx: dict[str, tuple[str, ...]] = {m: tuple(s) for m, s in rx.items()}
        self.signals: dict[tuple[str, str], tuple[str, float]] = dict(signals)
        self.offsets: dict[tuple[str, str], float] = dict(offsets or {})
        self.sync, self.tick = sync
        self.command, self.echo = echo
        self.uses: dict[str, tuple[str, ...]] = {**self.tx, self.sync: (self.tick,), **self.rx}
        self.lockstep: set[tuple[str, str]] = {sync, echo}  # the handshake's signals: no quantity of the plant
        where: dict[str, tuple[str, str, float, float]] = {
            quantity: (m, s, factor, self.offsets.get((m, s), 0.0)) for (m, s), (quantity, factor) in signals.items()}
        self.status: str = where["tcu_state"][0]
        self._reads: dict[str, tuple[str, float, float]] = {
            q: (where[q][1], where[q][2], where[q][3]) for q in where if q in _READ}
        # by status key, the quantity's number (the shipped DBC's) of each number the matrix sends, where its binding
        # names the values otherwise (values: by quantity, the matrix's number of each of the quantity's)
        self._numbers: dict[str, dict[float, float]] = {
            STATUS_KEYS[q]: {float(theirs): float(ours) for ours, theirs in numbers.items()}
            for q, numbers in (values or {}).items() if q in STATUS_KEYS}
        # the status values as the summary reads them: the very dict when the signals are the shipped DBC's
        self._status_as_is: bool = not self._numbers and all(
            self._reads[q] == (key, 1.0, 0.0) for q, key in STATUS_KEYS.items())
        self.plant_signals: Callable[[PlantOutputs, DriverInput], dict[str, dict[str, float]]] = self._encoder()

    def value_sources(self, message: str) -> dict[str, str]:
        """By signal of ``message``, the source of its value in the signal's unit from ``out`` (the plant's outputs)
        or ``driver`` (:attr:`signals`, constants inlined): always a float (``float()`` of a quantity that is not)."""
        return {signal: _to_dbc(*self.signals[message, signal], self.offsets.get((message, signal), 0.0))
                for signal in self.tx[message]}

    def _items(self, message: str) -> str:
        """The dict display of ``message``'s signal values (:meth:`value_sources`)."""
        return "{" + ", ".join(f"{signal!r}: {value}" for signal, value in self.value_sources(message).items()) + "}"

    def encoder_source(self) -> str:
        """The source of :attr:`plant_signals`, written out from :attr:`signals`: a dict display per message with
        its constants inlined, as fast as one written by hand."""
        lines = ["def plant_signals(out, driver):", "    return {"]
        lines += [f"        {message!r}: {self._items(message)}," for message in self.tx]
        return "\n".join([*lines, "    }", ""])

    def _encoder(self) -> Callable[[PlantOutputs, DriverInput], dict[str, dict[str, float]]]:
        """``plant_signals(out, driver)``: signal values of every message the plant sends (``{message: {signal:
        value}}``), in the signals' units, from the plant's outputs and the driver's input."""
        namespace: dict = {}
        exec(compile(self.encoder_source(), "<dsg_hil plant_signals>", "exec"), namespace)  # noqa: S102 - ours
        return namespace["plant_signals"]

    def frame_encoder(self, codec: Codec, message: str) -> Callable[[PlantOutputs, DriverInput, int], bytes]:
        """``f(out, driver, counter)``: the data of a frame of ``message`` the plant sends, its values as
        :attr:`plant_signals` gives them (:meth:`value_sources`), encoded by the codec without a dict in between
        where it can (:meth:`Codec.expression_encoder`; every source is a float, :meth:`value_sources`)."""
        return codec.expression_encoder(message, ("out", "driver"), self.value_sources(message), floats=True)

    def read(self, values: Mapping[str, float], quantity: str, default: float = 0.0) -> float:
        """``quantity`` in SI of a decoded frame's ``values`` (``default`` if the binding or the frame lacks it)."""
        found = self._reads.get(quantity)
        if found is None or found[0] not in values:
            return default
        signal, factor, offset = found
        value = values[signal] * factor
        return value + offset if offset != 0.0 else value

    def commanded_pressures(self, values: Mapping[str, float]) -> tuple[float, float]:
        """(P_CL_cmd, P_CH_cmd) [Pa] of a decoded command's values."""
        return self.read(values, "P_CL_cmd"), self.read(values, "P_CH_cmd")

    def commanded_decel(self, values: Mapping[str, float]) -> float:
        """The deceleration [m/s^2] a decoded command asks of the brakes (0 from a command without it)."""
        return self.read(values, "decel_request")

    def brake_request(self, values: Mapping[str, float]) -> float:
        """The TCU's brake request (0 or 1) of a decoded status (0 without one)."""
        return self.read(values, "brake_request")

    def status_values(self, values: dict[str, float]) -> dict[str, float]:
        """A decoded status's values as the summary reads them (the shipped DBC's signal names, :data:`STATUS_KEYS`,
        in SI): ``values`` itself when they are that already."""
        if self._status_as_is:
            return values
        read = {key: self.read(values, quantity) for quantity, key in STATUS_KEYS.items()}
        for key, numbers in self._numbers.items():  # (a number its value table lacks: -1, no state of the TCU's)
            read[key] = numbers.get(read[key], -1.0)
        return read


def plant_io(binding: str | None = None, dbc: str | None = None) -> PlantIO:
    """The plant's I/O of the binding file ``binding`` on the DBC ``dbc`` (None: the shipped ones)."""
    return from_binding(load_binding(binding, dbc=dbc))


def from_binding(binding: object) -> PlantIO:
    """The plant's I/O of a loaded :class:`dsg_hil.protocol.binding.Binding` (its plain tables)."""
    b: Any = binding
    return PlantIO(b.tx, b.rx, b.signals, b.sync, b.echo, b.offsets, b.values)


SHIPPED = from_binding(shipped_binding())  # the shipped DBC with its binding
PLANT_TX, PLANT_RX, SIGNALS, PLANT_USES = SHIPPED.tx, SHIPPED.rx, SHIPPED.signals, SHIPPED.uses
SYNC, LOCKSTEP = SHIPPED.sync, SHIPPED.lockstep
plant_signals = SHIPPED.plant_signals


def value_sources(message: str) -> dict[str, str]:
    """:meth:`PlantIO.value_sources` of the shipped binding."""
    return SHIPPED.value_sources(message)


def encoder_source() -> str:
    """:meth:`PlantIO.encoder_source` of the shipped binding."""
    return SHIPPED.encoder_source()


def frame_encoder(codec: Codec, message: str) -> Callable[[PlantOutputs, DriverInput, int], bytes]:
    """:meth:`PlantIO.frame_encoder` of the shipped binding."""
    return SHIPPED.frame_encoder(codec, message)


def commanded_pressures(values: Mapping[str, float]) -> tuple[float, float]:
    """(P_CL_cmd, P_CH_cmd) [Pa] of a decoded TCU_CMD's values (the shipped binding)."""
    return SHIPPED.commanded_pressures(values)


def commanded_decel(values: Mapping[str, float]) -> float:
    """The deceleration [m/s^2] a decoded TCU_CMD asks of the brakes (the shipped binding; 0 without it)."""
    return SHIPPED.commanded_decel(values)
