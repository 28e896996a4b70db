"""The plant's side of the CAN contract: which DBC messages it sends and reads, and one table, :data:`SIGNALS`, of
what each of their signals is in the plant's SI units. The table drives the encoding of the plant's frames
(:func:`frame_encoder`, from :func:`value_sources`; :func:`plant_signals` gives the values as dicts), the runner's
reading of TCU_CMD (:func:`commanded_pressures`) and the bus-log reader (:mod:`dsg_hil.paper.report.log`): r/min,
MPa and % exist at this edge only (:class:`dsg_hil.common.units.CV`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import get_type_hints

from ..common.units import CV
from ..physics.plant import PlantOutputs
from ..protocol.codec import Codec
from .scenario import DriverInput

__all__ = ["LOCKSTEP", "PLANT_RX", "PLANT_TX", "PLANT_USES", "SIGNALS", "SYNC", "commanded_decel",
           "commanded_pressures", "encoder_source", "frame_encoder", "plant_signals", "value_sources"]

PLANT_TX = {
    "PLANT_ENGINE": ("EngineSpeed", "EngineTorque"),
    "PLANT_SPEEDS": ("ClutchInputSpeed", "CLOutputSpeed", "CHOutputSpeed"),
    "PLANT_VEHICLE": ("TransOutputSpeed", "VehicleSpeed", "LongAccel"),
    "PLANT_PRESSURE": ("P_CL", "P_CH"),
    "PLANT_OIL_TEMP": ("T_OilCL", "T_OilCH", "T_Sump", "T_RadiatorOut"),
    "DRIVER": ("CreepRequest", "BrakePedal", "DesiredCreepSpeed"),
    "SIM_TRUTH_CL": ("T_Plate", "Mu", "Torque", "HeatFlux"),
    "SIM_TRUTH_CH": ("T_Plate", "Mu", "Torque", "HeatFlux"),
    "SIM_HEAT": ("HeatDissCL", "HeatDissCH"),
}
SYNC = "SIM_SYNC"
PLANT_RX = {
    "TCU_CMD": ("P_CL_Cmd", "P_CH_Cmd", "SyncEcho", "DecelRequest"),
    "TCU_STATUS": ("State", "ActiveClutch", "BrakeRequest", "T_CL_Pred", "T_CH_Pred", "FaultBits"),
}
PLANT_USES = {**PLANT_TX, SYNC: ("Tick",), **PLANT_RX}
LOCKSTEP = {(SYNC, "Tick"), ("TCU_CMD", "SyncEcho")}  # the lockstep handshake's signals: no quantity of the plant

_RPM, _MPA, _PERCENT = CV.RPM_TO_RAD_S, CV.MPA_TO_PA, CV.PERCENT_TO_FRACTION
# (message, signal) -> (quantity, factor): the signal's DBC value times ``factor`` is the quantity in SI (rad/s, Pa,
# m/s, N m, W, a fraction; degC as the plant has it). A quantity the plant sends is the attribute of that name of
# PlantOutputs (of DriverInput for DRIVER); one it reads is named here (LogSample's field in the log reader).
SIGNALS: dict[tuple[str, str], tuple[str, float]] = {
    ("PLANT_ENGINE", "EngineSpeed"): ("omega_e", _RPM),
    ("PLANT_ENGINE", "EngineTorque"): ("M_e", 1.0),
    ("PLANT_SPEEDS", "ClutchInputSpeed"): ("omega_in", _RPM),
    ("PLANT_SPEEDS", "CLOutputSpeed"): ("omega_CL", _RPM),
    ("PLANT_SPEEDS", "CHOutputSpeed"): ("omega_CH", _RPM),
    ("PLANT_VEHICLE", "TransOutputSpeed"): ("omega_out", _RPM),
    ("PLANT_VEHICLE", "VehicleSpeed"): ("v", 1.0),
    ("PLANT_VEHICLE", "LongAccel"): ("a_x", 1.0),
    ("PLANT_PRESSURE", "P_CL"): ("P_CL", _MPA),
    ("PLANT_PRESSURE", "P_CH"): ("P_CH", _MPA),
    ("PLANT_OIL_TEMP", "T_OilCL"): ("T_oil_CL", 1.0),
    ("PLANT_OIL_TEMP", "T_OilCH"): ("T_oil_CH", 1.0),
    ("PLANT_OIL_TEMP", "T_Sump"): ("T_sump", 1.0),
    ("PLANT_OIL_TEMP", "T_RadiatorOut"): ("T_radiator_out", 1.0),
    ("DRIVER", "CreepRequest"): ("creep_request", 1.0),
    ("DRIVER", "BrakePedal"): ("brake", _PERCENT),
    ("DRIVER", "DesiredCreepSpeed"): ("desired_speed_mps", 1.0),
    ("SIM_TRUTH_CL", "T_Plate"): ("T_CL", 1.0),
    ("SIM_TRUTH_CL", "Mu"): ("mu_CL", 1.0),
    ("SIM_TRUTH_CL", "Torque"): ("M_CL", 1.0),
    ("SIM_TRUTH_CL", "HeatFlux"): ("Q_CL", 1.0),
    ("SIM_TRUTH_CH", "T_Plate"): ("T_CH", 1.0),
    ("SIM_TRUTH_CH", "Mu"): ("mu_CH", 1.0),
    ("SIM_TRUTH_CH", "Torque"): ("M_CH", 1.0),
    ("SIM_TRUTH_CH", "HeatFlux"): ("Q_CH", 1.0),
    ("SIM_HEAT", "HeatDissCL"): ("Q_diss_CL", 1.0),
    ("SIM_HEAT", "HeatDissCH"): ("Q_diss_CH", 1.0),
    ("TCU_CMD", "P_CL_Cmd"): ("P_CL_cmd", _MPA),
    ("TCU_CMD", "P_CH_Cmd"): ("P_CH_cmd", _MPA),
    ("TCU_CMD", "DecelRequest"): ("decel_request", 1.0),
    ("TCU_STATUS", "State"): ("tcu_state", 1.0),
    ("TCU_STATUS", "ActiveClutch"): ("active_clutch", 1.0),
    ("TCU_STATUS", "BrakeRequest"): ("brake_request", 1.0),
    ("TCU_STATUS", "T_CL_Pred"): ("T_CL_pred", 1.0),
    ("TCU_STATUS", "T_CH_Pred"): ("T_CH_pred", 1.0),
    ("TCU_STATUS", "FaultBits"): ("fault_bits", 1.0),
}

_FLOATS = {source: {name for name, kind in get_type_hints(cls).items() if kind is float}  # the rest: float(...)
           for source, cls in (("out", PlantOutputs), ("driver", DriverInput))}


def _to_dbc(source: str, quantity: str, factor: float) -> str:
    """Source of a quantity of ``source`` (``out`` or ``driver``) in the DBC's unit: divided by the factor, written as
    a product with its reciprocal where the factor is below 1 (x 60/2pi for r/min, x 100 for %) and as a division
    where it is not (/ 1e6 for MPa): the constant that is exact where one is (the operations the plant always used,
    so its frames stay the same bit for bit)."""
    value = f"{source}.{quantity}"
    if factor == 1.0:
        return value if quantity in _FLOATS[source] else f"float({value})"
    return f"{value} * {1.0 / factor!r}" if factor < 1.0 else f"{value} / {factor!r}"


def value_sources(message: str) -> dict[str, str]:
    """By signal of ``message``, the source of its value in the DBC's unit from ``out`` (the plant's outputs) or
    ``driver`` (:data:`SIGNALS`, constants inlined): always a float (``float()`` of a quantity that is not one)."""
    source = "driver" if message == "DRIVER" else "out"
    return {signal: _to_dbc(source, *SIGNALS[message, signal]) for signal in PLANT_TX[message]}


def _items(message: str) -> str:
    """The dict display of ``message``'s signal values (:func:`value_sources`)."""
    return "{" + ", ".join(f"{signal!r}: {value}" for signal, value in value_sources(message).items()) + "}"


def encoder_source() -> str:
    """The source of :func:`plant_signals`, written out from :data:`SIGNALS`: a dict display per message with its
    constants inlined, as fast as one written by hand."""
    lines = ["def plant_signals(out, driver):", "    return {"]
    lines += [f"        {message!r}: {_items(message)}," for message in PLANT_TX]
    return "\n".join([*lines, "    }", ""])


def _encoder() -> Callable[[PlantOutputs, DriverInput], dict[str, dict[str, float]]]:
    namespace: dict = {}
    exec(compile(encoder_source(), "<dsg_hil plant_signals>", "exec"), namespace)  # noqa: S102 - our own source
    return namespace["plant_signals"]


plant_signals = _encoder()
plant_signals.__doc__ = """Signal values of every message the plant sends (``{message: {signal: value}}``), in DBC
units, from the plant's outputs ``out`` and the driver's input (:data:`SIGNALS`; its source: :func:`encoder_source`)."""


def frame_encoder(codec: Codec, message: str) -> Callable[[PlantOutputs, DriverInput, int], bytes]:
    """``f(out, driver, counter)``: the data of a frame of ``message`` the plant sends, its values as
    :func:`plant_signals` gives them (:func:`value_sources`), encoded by the codec without a dict in between where
    it can (:meth:`Codec.expression_encoder`; every source is a float, :func:`value_sources`)."""
    return codec.expression_encoder(message, ("out", "driver"), value_sources(message), floats=True)


(_CL, _CL_TO_PA), (_CH, _CH_TO_PA) = (
    next((signal, factor) for (message, signal), (name, factor) in SIGNALS.items() if (message, name) == key)
    for key in (("TCU_CMD", "P_CL_cmd"), ("TCU_CMD", "P_CH_cmd")))
_DECEL, _DECEL_FACTOR = next((signal, factor) for (message, signal), (name, factor) in SIGNALS.items()
                             if (message, name) == ("TCU_CMD", "decel_request"))


def commanded_pressures(values: Mapping[str, float]) -> tuple[float, float]:
    """(P_CL_cmd, P_CH_cmd) [Pa] of a decoded TCU_CMD's values (:data:`SIGNALS`)."""
    return values[_CL] * _CL_TO_PA, values[_CH] * _CH_TO_PA


def commanded_decel(values: Mapping[str, float]) -> float:
    """The deceleration [m/s^2] a decoded TCU_CMD asks of the brakes (:data:`SIGNALS`; 0 from a TCU_CMD without it)."""
    return values.get(_DECEL, 0.0) * _DECEL_FACTOR
