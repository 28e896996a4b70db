"""The FMUs' variables, named after the DBC: one table for each direction, derived from the plant's CAN edge
(:data:`dsg_hil.sim.plant_io.SIGNALS`) and the DBC, never written out by hand.

A variable carries the DBC signal's name, unit (one spelling for the FMUs: :func:`~dsg_hil.fmi.units.fmi_unit`)
and range. Where two messages share a signal name (SIM_TRUTH_CL and SIM_TRUTH_CH both have ``T_Plate``), the
variable is ``MESSAGE.Signal`` (FMI's structured naming). Its type (:func:`kind_of`): a 1-bit flag is an FMI
Boolean, a dimensionless whole number (a state of a value table, a bit field) an Integer, every other signal a Real
in the DBC's physical unit (r/min, MPa, %, degC).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any

from ecu_stub.runner import TCU_RX, TCU_TX

from ..protocol import load_dbc
from ..sim.plant_io import PLANT_RX, PLANT_TX, SYNC
from .units import fmi_unit

__all__ = ["BUS_INPUTS", "BUS_SIGNALS", "PLANT_INPUTS", "PLANT_OUTPUTS", "TCU_INPUTS", "TCU_OUTPUTS", "Signal",
           "kind_of", "signals", "variable_names"]


@dataclass(frozen=True)
class Signal:
    """One FMU variable that is a DBC signal: the message and signal, the FMU name, the DBC's unit and range
    (None where the DBC gives none)."""

    message: str
    signal: str
    name: str
    unit: str
    minimum: float | None = None
    maximum: float | None = None
    kind: str = "Real"  # the FMI type: Real, Integer or Boolean


def variable_names(pairs: list[tuple[str, str]]) -> list[str]:
    """The FMU names of (message, signal) pairs: the signal's name, or ``MESSAGE.Signal`` where it is not unique."""
    counts = Counter(signal for _, signal in pairs)
    return [signal if counts[signal] == 1 else f"{message}.{signal}" for message, signal in pairs]


def signals(table: dict[str, tuple[str, ...]], skip: frozenset[str] = frozenset()) -> tuple[Signal, ...]:
    """The signals of ``{message: (signal, ...)}`` (without the signals named in ``skip``), with their DBC units."""
    db = load_dbc()
    pairs = [(message, signal) for message, names in table.items() for signal in names if signal not in skip]
    found = [db.get_message_by_name(message).get_signal_by_name(signal) for message, signal in pairs]
    return tuple(Signal(m, s, name, fmi_unit(f.unit), _bound(f.minimum), _bound(f.maximum), kind_of(f))
                 for (m, s), name, f in zip(pairs, variable_names(pairs), found))


def kind_of(signal: Any) -> str:
    """The FMI type of a cantools signal: Boolean (1 bit, raw = physical), Integer (raw = physical, no unit), Real."""
    whole = signal.scale == 1 and signal.offset == 0 and not signal.is_float
    if whole and signal.length == 1:
        return "Boolean"
    return "Integer" if whole and fmi_unit(signal.unit) == "1" else "Real"


def _bound(value: float | None) -> float | None:
    return None if value is None else float(value)


_TRUTH_AND_SENSORS = {message: names for message, names in PLANT_TX.items() if message != "DRIVER"}
PLANT_OUTPUTS = signals(_TRUTH_AND_SENSORS)  # every signal the plant sends but the driver's, SIM_* truth included
# The plant's inputs: the TCU's commands it acts on (pressures, brake request) and the driver's (the scenario)
PLANT_INPUTS = signals({"TCU_CMD": PLANT_RX["TCU_CMD"], "TCU_STATUS": ("BrakeRequest",),
                        "DRIVER": PLANT_TX["DRIVER"]}, skip=frozenset({"SyncEcho"}))
# The TCU's side (ecu-stub's, without the lock-step handshake): what a controller FMU reads and writes.
# BUS_INPUTS: what the bus side (ecu-stub's receive checks) adds, by name (to TcuInputs' fields).
TCU_INPUTS = signals({message: names for message, names in TCU_RX.items() if message != SYNC})
TCU_OUTPUTS = signals(TCU_TX, skip=frozenset({"SyncEcho"}))
BUS_INPUTS = {"PlantValid": "plant_valid", "RxFaultBits": "fault_bits"}
BUS_SIGNALS = (Signal("", "", "PlantValid", "1", 0.0, 1.0, "Boolean"), Signal("", "", "RxFaultBits", "1", 0.0, 255.0,
                                                                             "Integer"))
