"""The plant as an FMI 2.0 co-simulation slave (PythonFMU): :class:`PlantSlave` wraps
:class:`dsg_hil.physics.plant.Plant`.

* Inputs (DBC names and units, :data:`~dsg_hil.fmi.signals.PLANT_INPUTS`): the TCU's pressure commands, brake
  request and deceleration request, the driver's creep request, brake pedal and desired speed (a host scripts the
  scenario with them).
* Outputs (:data:`~dsg_hil.fmi.signals.PLANT_OUTPUTS`): every signal the plant sends on CAN but the driver's,
  the simulation-only truth (SIM_*) included, in the DBC's units, computed by the plant's own encoder table
  (:func:`dsg_hil.sim.plant_io.plant_signals`) but not quantised to the DBC's resolution.
* Parameters: every value of the parameter file (SI, its unit and source in the description), the initial
  state (``init.*``, default: the shipped creep scenario) and the fixed internal step ``dt``.

A communication step must be a whole number of internal steps (else it is discarded, fmi2Discard); over it the
inputs are held, as in :meth:`Plant.advance`: brake = max(BrakePedal, BrakeRequest, the brake for DecelRequest),
grade and engine speed those of the parameters (``vehicle.beta``, idle). The FMU state (get/set/serialise) is the
plant's whole array (the contacts' modes included), the variables (inputs and parameters: a state of an instance
with other parameters rebuilds the plant with them) and the time, so a host can roll back to the bit.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Causality

from ..physics.params import Params, load_params, with_overrides
from ..physics.plant import Plant, PlantInputs, PlantOutputs
from ..physics.powertrain import brake_for_decel
from ..sim.plant_io import SIGNALS, commanded_decel, commanded_pressures, plant_signals
from ..sim.run import plant_for
from ..sim.scenario import DriverInput, Scenario, load_scenario
from .export import PARAMS_RESOURCE
from .signals import PLANT_INPUTS, PLANT_OUTPUTS
from .slave import FmuCallError, SignalSlave

__all__ = ["INIT", "PlantSlave", "parameter_table"]

_PERCENT = SIGNALS["DRIVER", "BrakePedal"][1]  # BrakePedal [%] -> the plant's brake, 0..1
# The initial state: parameter name -> (Scenario field, unit, description)
INIT = {"init.T_CL": ("T_CL_c", "degC", "CL plate temperature at t = 0"),
        "init.T_CH": ("T_CH_c", "degC", "CH plate temperature at t = 0"),
        "init.T_oil": ("T_oil_c", "degC", "every other thermal node (oil, sump, housing) at t = 0"),
        "init.v": ("v_mps", "m/s", "vehicle speed at t = 0")}


def parameter_table(params: Params) -> list[tuple[str, float, str, str]]:
    """(dotted key, value, unit, 'source: reason') of every parameter, in the file's order."""
    rows = []
    for key, (source, reason) in params.provenance.items():
        *path, name = key.split(".")
        obj: Any = params
        for part in path:
            obj = getattr(obj, part)
        unit = next(f.metadata["unit"] for f in dataclasses.fields(obj) if f.name == name)
        rows.append((key, float(getattr(obj, name)), unit, f"{source}: {reason}"))
    return rows


class PlantSlave(SignalSlave):
    """The plant behind the FMI 2.0 co-simulation interface (see the module docstring)."""

    description = ("dsg-hil: the DSG dual wet clutch plant (Ma et al.), signals named and scaled as in the DBC. "
                   "Needs dsg_hil installed in the host's Python.")
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.01)
    model = "plant"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        resources = Path(self.resources) if self.resources else None
        given = resources / PARAMS_RESOURCE if resources is not None else None
        self._params = load_params(given if given is not None and given.is_file() else None)
        self._scenario: Scenario = load_scenario()
        for key, value, unit, why in parameter_table(self._params):
            self.real(key, value, unit, Fmi2Causality.parameter, f"[{unit}] {why}")
        for key, (field, unit, what) in INIT.items():
            self.real(key, float(getattr(self._scenario, field)), unit, Fmi2Causality.parameter,
                       f"[{unit}] {what} (default: the shipped creep scenario)")
        self.real("dt", 1e-3, "s", Fmi2Causality.parameter,
                   "[s] the plant's fixed internal step; a communication step must be a whole multiple of it")
        for signal in PLANT_INPUTS:
            self.signal(signal, Fmi2Causality.input)
        for signal in PLANT_OUTPUTS:
            self.signal(signal, Fmi2Causality.output)
        self.plant: Plant | None = None
        self.out: PlantOutputs | None = None
        self._parameter_keys = [key for key in self.values if self.causalities[key] == Fmi2Causality.parameter]
        self._built_with: dict[str, float] = {}
        self._fresh = np.zeros(0)
        self.seal()

    # ---- the simulation --------------------------------------------------------------------------------------
    def initialise(self) -> None:
        """The plant, built from the parameters as set now (a changed one checked as ``dsg-hil --set`` checks it)."""
        self._build()
        assert self.plant is not None
        self._publish(self.plant.outputs())

    def _build(self) -> None:
        values = self.values
        parameters = {key: values[key] for key in self._parameter_keys}
        if self.plant is not None and parameters == self._built_with:
            self.plant.restore(self._fresh)
            return
        changed = {key: values[key] for key, value, _, _ in parameter_table(self._params) if values[key] != value}
        params = with_overrides(self._params, changed, origin="FMU parameter") if changed else self._params
        initial: dict[str, Any] = {field: values[key] for key, (field, _, _) in INIT.items()}
        scenario = dataclasses.replace(self._scenario, **initial)
        self.plant = plant_for(scenario, params, dt=values["dt"])
        self._fresh, self._built_with = self.plant.snapshot(), parameters

    def step(self, current_time: float, step_size: float) -> None:
        plant = self.plant
        assert plant is not None  # SignalSlave steps an initialised FMU only
        steps = round(step_size * 1e9 / plant.dt_ns)
        if abs(step_size * 1e9 - steps * plant.dt_ns) > 1e-3:
            raise FmuCallError(f"communication step {step_size!r} s: not a whole number of internal steps of "
                               f"{plant.dt} s (dt)")
        if steps:
            self._publish(plant.advance(self.inputs(), steps))

    def inputs(self) -> PlantInputs:
        """The plant's inputs from the input variables, converted to SI as the plant's CAN edge converts them."""
        v, plant = self.values, self.plant
        assert plant is not None
        P_CL, P_CH = commanded_pressures(v)
        brake = max(v["BrakePedal"] * _PERCENT, v["BrakeRequest"])
        if (decel := commanded_decel(v)) > 0.0:  # the brakes as a brake controller takes a deceleration
            brake = max(brake, brake_for_decel(decel, plant.params.vehicle))
        return PlantInputs(P_CL_cmd=P_CL, P_CH_cmd=P_CH, brake=brake)

    def _publish(self, out: PlantOutputs) -> None:
        self.out = out
        v = self.values
        driver = DriverInput(out.t, v["CreepRequest"] >= 0.5, v["BrakePedal"] * _PERCENT, v["DesiredCreepSpeed"])
        values = plant_signals(out, driver)
        for signal in PLANT_OUTPUTS:
            v[signal.name] = float(values[signal.message][signal.signal])

    # ---- FMU state: the plant's whole array (contact modes included) and, with the variables, its parameters ---
    def snapshot(self) -> dict[str, Any]:
        plant = self.plant
        return {"plant": None if plant is None or self.phase == "instantiated" else plant.snapshot().tolist()}

    def restore(self, state: dict[str, Any]) -> None:
        if state["plant"] is None:  # a state before initialisation: no plant yet
            self.plant, self.out = None, None
            return
        self._build()  # the state's parameters (rebuilt only where they differ)
        assert self.plant is not None
        self.plant.restore(np.asarray(state["plant"], dtype=float))
        self.out = self.plant.outputs()
