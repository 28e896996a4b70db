"""ecu-stub's controller in FMU terms: the conversions between its ``TcuInputs``/``TcuOutputs`` and the DBC signals
a controller FMU reads and writes (:data:`~dsg_hil.fmi.signals.TCU_INPUTS`, ``TCU_OUTPUTS``), used both by the
adapter that runs a controller FMU (:mod:`dsg_hil.fmi.controller`) and by ecu-stub's controller as an FMU
(:mod:`dsg_hil.fmi.tcu_slave`).

A controller FMU's step is one control cycle: the host sets the inputs at ``t`` and calls ``doStep(t, h)``; the
outputs are then the commands for ``t`` (a discrete controller sampled at the communication point with direct
feedthrough, as a fixed-step Simulink export with step h computes them), held until the next cycle.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ecu_stub.controller import TcuInputs, TcuOutputs
from ecu_stub.runner import TCU_USES

from ..protocol import Codec, load_dbc
from ..protocol.lockstep import choices
from .signals import BUS_INPUTS

__all__ = ["INPUT_FIELDS", "OPTIONAL_OUTPUTS", "OUTPUT_FIELDS", "ValueTables", "input_values", "output_values",
           "tcu_inputs", "tcu_outputs"]

# DBC signal (FMU variable) -> the field of ecu-stub's TcuInputs / TcuOutputs (as ecu_stub.runner fills them)
INPUT_FIELDS = {"EngineSpeed": "engine_speed_rpm", "ClutchInputSpeed": "clutch_in_rpm", "CLOutputSpeed": "cl_out_rpm",
                "CHOutputSpeed": "ch_out_rpm", "VehicleSpeed": "v_mps", "LongAccel": "accel_mps2",
                "P_CL": "P_CL_mpa", "P_CH": "P_CH_mpa",
                "T_OilCL": "T_oil_CL_c", "T_OilCH": "T_oil_CH_c", "T_Sump": "T_sump_c",
                "CreepRequest": "creep_request", "BrakePedal": "brake_pct", "DesiredCreepSpeed": "desired_speed_mps",
                **BUS_INPUTS}
OUTPUT_FIELDS = {"P_CL_Cmd": "P_CL_cmd_mpa", "P_CH_Cmd": "P_CH_cmd_mpa", "DecelRequest": "decel_request_mps2",
                 "State": "state", "ActiveClutch": "active_clutch", "BrakeRequest": "brake_request",
                 "T_CL_Pred": "T_CL_pred_c", "T_CH_Pred": "T_CH_pred_c", "FaultBits": "fault_bits"}
OPTIONAL_OUTPUTS = {"DecelRequest": 0.0}  # a controller FMU may leave these out: this value then (no deceleration)
_FLAGS = {"plant_valid", "creep_request", "brake_request"}  # 0.0 / 1.0 on the FMU side
_WHOLE = {"fault_bits"}


class ValueTables:
    """The value tables of the TCU's State and ActiveClutch (name <-> number): the shipped DBC's TCU_STATUS (or
    ``codec``'s), or the run's matrix's (``states``, ``clutches``: {name: number}, as a binding's
    ``ecu_stub.tcu_io.TcuIO`` gives them, ``state_values`` and ``clutch_values``)."""

    def __init__(self, codec: Codec | None = None, states: Mapping[str, int] | None = None,
                 clutches: Mapping[str, int] | None = None) -> None:
        if states is None or clutches is None:
            codec = codec or Codec(load_dbc(), TCU_USES)
            states = states if states is not None else choices(codec, "TCU_STATUS", "State")
            clutches = clutches if clutches is not None else choices(codec, "TCU_STATUS", "ActiveClutch")
        self.states, self.clutches = dict(states), dict(clutches)
        self.state_names = {value: name for name, value in self.states.items()}
        self.clutch_names = {value: name for name, value in self.clutches.items()}


def input_values(inputs: TcuInputs) -> dict[str, float]:
    """The FMU inputs (DBC signal -> value) of ecu-stub's controller inputs."""
    return {name: float(getattr(inputs, field)) for name, field in INPUT_FIELDS.items()}


def _fields(values: Mapping[str, float], table: Mapping[str, str]) -> dict[str, Any]:
    """The dataclass fields of FMU values by ``table`` (flags: >= 0.5, as the TCU reads a 1-bit signal)."""
    fields: dict[str, Any] = {}
    for name, field in table.items():
        value = values.get(name, OPTIONAL_OUTPUTS[name]) if name in OPTIONAL_OUTPUTS else values[name]
        fields[field] = value >= 0.5 if field in _FLAGS else int(value) if field in _WHOLE else value
    return fields


def tcu_inputs(values: Mapping[str, float]) -> TcuInputs:
    """ecu-stub's controller inputs from FMU input values."""
    return TcuInputs(**_fields(values, INPUT_FIELDS))


def output_values(outputs: TcuOutputs, tables: ValueTables) -> dict[str, float]:
    """The FMU outputs (DBC signal -> value) of ecu-stub's controller outputs (State, ActiveClutch: the DBC's
    numbers)."""
    values = {name: getattr(outputs, field) for name, field in OUTPUT_FIELDS.items()}
    values["State"], values["ActiveClutch"] = tables.states[outputs.state], tables.clutches[outputs.active_clutch]
    return {name: float(value) for name, value in values.items()}


def tcu_outputs(values: Mapping[str, float], tables: ValueTables) -> TcuOutputs:
    """ecu-stub's controller outputs from FMU output values; a State or ActiveClutch the DBC does not name is a
    ValueError naming it."""
    fields = _fields(values, OUTPUT_FIELDS)
    for name, field, table in (("State", "state", tables.state_names),
                               ("ActiveClutch", "active_clutch", tables.clutch_names)):
        number = int(values[name])
        if number != values[name] or number not in table:
            raise ValueError(f"controller output {name} = {values[name]:g}: not a value of the DBC's table "
                             f"({', '.join(f'{v} {n}' for v, n in sorted(table.items()))})")
        fields[field] = table[number]
    return TcuOutputs(**fields)
