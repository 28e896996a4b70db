"""The plant FMU and a controller FMU together in FMPy, without CAN: each control period at ``t`` the controller
reads the plant's outputs at ``t`` (and the scenario's driver), steps, and the plant steps over the period on its
commands, the same order as a lock-step run (:meth:`dsg_hil.sim.runner.PlantRunner.run_lockstep`). The variables
are connected by name: what the controller reads is what the plant outputs (DBC names), and the reverse.

``as_on_can``: each signal is passed as CAN would carry it, sampled at its message's DBC cycle time (held in
between) and rounded to the signal's resolution; else every signal every period, unrounded. Either way not bit for
bit a ``dsg-hil run`` (CAN's encoding clamps and rounds in its own way, and the lock-step run starts with a presence
handshake), but the same creep.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..protocol import load_dbc
from ..sim.plant_io import SIGNALS
from ..sim.scenario import Scenario, load_scenario
from .host import get_values, instantiate, set_values
from .signals import PLANT_INPUTS, PLANT_OUTPUTS, TCU_OUTPUTS

__all__ = ["CoSimulation", "cosimulate", "open_fmu"]

_TO_PERCENT = 1.0 / SIGNALS["DRIVER", "BrakePedal"][1]  # the scenario's brake 0..1 -> BrakePedal [%]


@dataclass
class CoSimulation:
    """Each control period's end (``t`` [s], the plates ``T_CL``, ``T_CH`` [degC]) and the handovers, as a run's
    summary counts them: the controller's ActiveClutch changed between CL and CH, (t [s], from, to)."""

    t: list[float] = field(default_factory=list)
    T_CL: list[float] = field(default_factory=list)
    T_CH: list[float] = field(default_factory=list)
    handovers: list[tuple[float, str, str]] = field(default_factory=list)


def open_fmu(path: str | Path, name: str) -> tuple[Any, dict[str, tuple[str, int]]]:
    """An FMI 2.0 co-simulation FMU instantiated and initialised through FMPy; its variables' (type, value
    reference) by name."""
    from fmpy import extract, read_model_description  # noqa: PLC0415 - the fmi extra
    from fmpy.fmi2 import FMU2Slave  # noqa: PLC0415

    md = read_model_description(str(path))
    unzipped = extract(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=name)
    instantiate(fmu, unzipped)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    return fmu, {v.name: (v.type, v.valueReference) for v in md.modelVariables}


class _Link:
    """Signals passed from one FMU to the other, as CAN would carry them (``as_on_can``) or as they are."""

    def __init__(self, names: list[str], as_on_can: bool, period_ms: int) -> None:
        db = load_dbc()
        by_name = {s.name: s for s in (*PLANT_OUTPUTS, *PLANT_INPUTS, *TCU_OUTPUTS)}
        self.names, self.as_on_can, self.period_ms = names, as_on_can, period_ms
        self.cycles, self.scales, self.held = [], [], [0.0] * len(names)
        for name in names:
            message = db.get_message_by_name(by_name[name].message)
            signal = message.get_signal_by_name(by_name[name].signal)
            self.cycles.append(int(message.cycle_time or period_ms))
            self.scales.append((float(signal.scale), float(signal.offset)))

    def pass_on(self, k: int, values: list[float]) -> list[float]:
        """The values the receiving side has in period k."""
        if not self.as_on_can:
            return values
        for i, (value, cycle, (scale, offset)) in enumerate(zip(values, self.cycles, self.scales)):
            if k * self.period_ms % cycle == 0:
                self.held[i] = round((value - offset) / scale) * scale + offset
        return list(self.held)


def cosimulate(plant_fmu: str | Path, controller_fmu: str | Path, scenario: Scenario | None = None,
               duration: float | None = None, period: float = 0.01, as_on_can: bool = True) -> CoSimulation:
    """Run ``scenario`` (default: the shipped creep) for ``duration`` [s] with the two FMUs, one instance each
    (PythonFMU's FMUs: one per process). The plant FMU's initial state is its parameters' (``init.*``);
    ``as_on_can``: see the module docstring."""
    from .tcu import ValueTables  # noqa: PLC0415

    scenario = scenario or load_scenario()
    plant, p = open_fmu(plant_fmu, "plant")
    tcu, c = open_fmu(controller_fmu, "tcu")
    tables = ValueTables()
    reads = [name for name in (s.name for s in PLANT_OUTPUTS) if name in c]
    commands = [s.name for s in PLANT_INPUTS if s.name in c and s.message != "DRIVER"]
    period_ms = round(period * 1000)
    to_tcu, to_plant = _Link(reads, as_on_can, period_ms), _Link(commands, as_on_can, period_ms)
    status = _Link(["ActiveClutch"], as_on_can, period_ms)  # as the plant's summary sees it: TCU_STATUS
    T_CL, T_CH = p["SIM_TRUTH_CL.T_Plate"], p["SIM_TRUTH_CH.T_Plate"]
    result, active = CoSimulation(), "NONE"
    if "PlantValid" in c:
        set_values(tcu, [c["PlantValid"]], [1.0])
    for k in range(round((duration or scenario.duration_s) / period)):
        t = k * period
        driver = scenario.driver_at(t)
        pedal = {"CreepRequest": float(driver.creep_request), "BrakePedal": driver.brake * _TO_PERCENT,
                 "DesiredCreepSpeed": driver.desired_speed_mps}
        set_values(tcu, [c[n] for n in reads] + [c[n] for n in pedal if n in c],
                   to_tcu.pass_on(k, get_values(plant, [p[n] for n in reads]))
                   + [v for n, v in pedal.items() if n in c])
        tcu.doStep(currentCommunicationPoint=t, communicationStepSize=period)
        values = to_plant.pass_on(k, get_values(tcu, [c[n] for n in commands]))
        set_values(plant, [p[n] for n in commands] + [p[n] for n in pedal], values + list(pedal.values()))
        plant.doStep(currentCommunicationPoint=t, communicationStepSize=period)
        now = tables.clutch_names[int(status.pass_on(k, get_values(tcu, [c["ActiveClutch"]]))[0])]
        if now in ("CL", "CH") and active in ("CL", "CH") and now != active:
            result.handovers.append((t, active, now))
        active = now
        result.t.append((k + 1) * period)
        T = get_values(plant, [T_CL, T_CH])
        result.T_CL.append(T[0])
        result.T_CH.append(T[1])
    for fmu in (tcu, plant):
        fmu.terminate()
        fmu.freeInstance()
    return result
