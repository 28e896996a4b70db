"""The plant's side of the CAN contract: which DBC messages it sends and reads, and the conversion between the
plant's SI outputs and the DBC's signals (r/min, MPa, degC at this edge only)."""

from __future__ import annotations

from ..physics.friction import RAD_S_TO_RPM
from ..physics.plant import PlantOutputs
from .scenario import DriverInput

PLANT_TX = {
    "PLANT_ENGINE": ("EngineSpeed", "EngineTorque"),
    "PLANT_SPEEDS": ("ClutchInputSpeed", "CLOutputSpeed", "CHOutputSpeed"),
    "PLANT_VEHICLE": ("TransOutputSpeed", "VehicleSpeed"),
    "PLANT_PRESSURE": ("P_CL", "P_CH"),
    "PLANT_OIL_TEMP": ("T_OilCL", "T_OilCH", "T_Sump", "T_RadiatorOut"),
    "DRIVER": ("CreepRequest", "BrakePedal", "DesiredCreepSpeed"),
    "SIM_TRUTH_CL": ("T_Plate", "Mu", "Torque", "HeatFlux"),
    "SIM_TRUTH_CH": ("T_Plate", "Mu", "Torque", "HeatFlux"),
    "SIM_HEAT": ("HeatDissCL", "HeatDissCH"),
}
SYNC = "SIM_SYNC"
PLANT_RX = {
    "TCU_CMD": ("P_CL_Cmd", "P_CH_Cmd", "SyncEcho"),
    "TCU_STATUS": ("State", "ActiveClutch", "BrakeRequest", "T_CL_Pred", "T_CH_Pred", "FaultBits"),
}
PLANT_USES = {**PLANT_TX, SYNC: ("Tick",), **PLANT_RX}


def plant_signals(out: PlantOutputs, driver: DriverInput) -> dict[str, dict[str, float]]:
    """Signal values of every message the plant sends, in DBC units."""
    return {
        "PLANT_ENGINE": {"EngineSpeed": out.omega_e * RAD_S_TO_RPM, "EngineTorque": out.M_e},
        "PLANT_SPEEDS": {"ClutchInputSpeed": out.omega_in * RAD_S_TO_RPM, "CLOutputSpeed": out.omega_CL * RAD_S_TO_RPM,
                         "CHOutputSpeed": out.omega_CH * RAD_S_TO_RPM},
        "PLANT_VEHICLE": {"TransOutputSpeed": out.omega_out * RAD_S_TO_RPM, "VehicleSpeed": out.v},
        "PLANT_PRESSURE": {"P_CL": out.P_CL / 1e6, "P_CH": out.P_CH / 1e6},
        "PLANT_OIL_TEMP": {"T_OilCL": out.T_oil_CL, "T_OilCH": out.T_oil_CH, "T_Sump": out.T_sump,
                           "T_RadiatorOut": out.T_radiator_out},
        "DRIVER": {"CreepRequest": float(driver.creep_request), "BrakePedal": driver.brake * 100.0,
                   "DesiredCreepSpeed": driver.desired_speed_mps},
        "SIM_TRUTH_CL": {"T_Plate": out.T_CL, "Mu": out.mu_CL, "Torque": out.M_CL, "HeatFlux": out.Q_CL},
        "SIM_TRUTH_CH": {"T_Plate": out.T_CH, "Mu": out.mu_CH, "Torque": out.M_CH, "HeatFlux": out.Q_CH},
        "SIM_HEAT": {"HeatDissCL": out.Q_diss_CL, "HeatDissCH": out.Q_diss_CH},
    }
