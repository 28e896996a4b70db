"""Worked example frames of the contract: one per message, at a typical moment of a creep (CL slipping, the
vehicle at 0.22 m/s on the grade), encoded by the codec with counter 3. docs/reference/can.md prints
them (a test checks it prints exactly these bytes); docs/reference/contract.md points there."""

from __future__ import annotations

from cantools.database.can import Database

from .codec import Codec

__all__ = ["EXAMPLE_COUNTER", "EXAMPLE_VALUES", "example_frames"]

EXAMPLE_COUNTER = 3
EXAMPLE_VALUES: dict[str, dict[str, float]] = {
    "PLANT_ENGINE": {"EngineSpeed": 800.0, "EngineTorque": 171.3},
    "PLANT_SPEEDS": {"ClutchInputSpeed": 149.3, "CLOutputSpeed": 60.6, "CHOutputSpeed": 35.1},
    "PLANT_VEHICLE": {"TransOutputSpeed": 41.2, "VehicleSpeed": 0.22, "LongAccel": 1.698},
    "PLANT_PRESSURE": {"P_CL": 0.5012, "P_CH": 0.0},
    "PLANT_OIL_TEMP": {"T_OilCL": 104.2, "T_OilCH": 96.5, "T_Sump": 92.0, "T_RadiatorOut": 88.4},
    "DRIVER": {"CreepRequest": 1, "BrakePedal": 0.0, "DesiredCreepSpeed": 0.22},
    "TCU_CMD": {"P_CL_Cmd": 0.5, "P_CH_Cmd": 0.0, "SyncEcho": 0x2A, "DecelRequest": 0.0},
    "TCU_STATUS": {"State": 2, "ActiveClutch": 1, "BrakeRequest": 0, "T_CL_Pred": 187.4, "T_CH_Pred": 101.2,
                   "FaultBits": 0},
    "SIM_TRUTH_CL": {"T_Plate": 188.1, "Mu": 0.0655, "Torque": 842.5, "HeatFlux": 7820.0},
    "SIM_TRUTH_CH": {"T_Plate": 101.0, "Mu": 0.0, "Torque": 0.0, "HeatFlux": 0.0},
    "SIM_HEAT": {"HeatDissCL": 2140.0, "HeatDissCH": 160.0},
    "SIM_SYNC": {"Tick": 4394},
}


def example_frames(db: Database) -> list[tuple[str, int, dict[str, float], bytes]]:
    """(message, frame ID, signal values, data) for every DBC message that has example values, in DBC order."""
    names = [m.name for m in db.messages if m.name in EXAMPLE_VALUES]
    codec = Codec(db, {name: tuple(EXAMPLE_VALUES[name]) for name in names})
    return [(name, codec.frame_id(name), EXAMPLE_VALUES[name],
             codec.encode(name, EXAMPLE_VALUES[name], EXAMPLE_COUNTER)) for name in names]
