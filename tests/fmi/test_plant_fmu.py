"""The plant FMU: valid for FMPy, the variables the DBC gives, the in-process plant's trajectory to the last bit,
parameters set before initialisation, and an FMU state that rolls the plant back whole."""

from __future__ import annotations

import json

import numpy as np
from fmpy import read_model_description
from fmpy.validation import validate_fmu
import pytest

from dsg_hil.common.units import CV
from dsg_hil.fmi.signals import PLANT_INPUTS, PLANT_OUTPUTS
from dsg_hil.fmi.units import fmi_unit
from dsg_hil.physics.params import load_params
from dsg_hil.physics.plant import PlantInputs
from dsg_hil.protocol import load_dbc
from dsg_hil.sim.plant_io import PLANT_TX, plant_signals
from dsg_hil.sim.run import plant_for
from dsg_hil.sim.scenario import DriverInput, load_scenario

from .conftest import run_python

# A scripted test drive (t_start [s], P_CL_Cmd [MPa], P_CH_Cmd [MPa], BrakePedal [%]): held from t_start on
SCRIPT = [(0.0, 0.0, 0.0, 100.0), (0.3, 0.0, 0.0, 0.0), (0.5, 0.6, 0.0, 0.0), (1.0, 0.6, 0.4, 0.0),
          (2.0, 0.3, 0.7, 0.0)]
STOP, STEP = 3.0, 0.01


def test_both_fmus_validate(fmus):
    for path in fmus.values():
        assert validate_fmu(str(path)) == []


def test_the_plant_fmu_has_the_dbc_s_signals_and_every_parameter(fmus):
    md = read_model_description(str(fmus["plant"]))
    by = {c: [v for v in md.modelVariables if v.causality == c] for c in ("input", "output", "parameter")}
    db = load_dbc()
    assert [v.name for v in by["input"]] == ["P_CL_Cmd", "P_CH_Cmd", "DecelRequest", "BrakeRequest", "CreepRequest",
                                             "BrakePedal", "DesiredCreepSpeed"]
    sent = [(m, s) for m, names in PLANT_TX.items() if m != "DRIVER" for s in names]
    assert len(by["output"]) == len(sent) == 24
    for variable, (message, signal) in zip(by["output"], sent):
        assert variable.name.rpartition(".")[2] == signal
        unit = db.get_message_by_name(message).get_signal_by_name(signal).unit
        assert variable.unit == fmi_unit(unit)
    params = load_params()
    assert len(by["parameter"]) == len(params.provenance) + 5  # the file's values, init.* (4), dt
    named = {v.name: v for v in by["parameter"]}
    assert float(named["vehicle.m"].start) == params.vehicle.m
    assert named["vehicle.m"].unit == "kg" and "paper" in named["vehicle.m"].description
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate


def test_units_have_one_spelling_and_a_base_unit_and_inputs_the_dbc_s_range(fmus):
    db = load_dbc()
    for path in fmus.values():
        md = read_model_description(str(path))
        used = {v.unit for v in md.modelVariables if v.unit is not None}
        defined = {u.name: u.baseUnit for u in md.unitDefinitions}
        assert used == set(defined) and all(base is not None for base in defined.values()), path
        # one spelling: no two names for the same SI base unit with the same factor and offset
        keys = [(tuple(getattr(b, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")), b.factor, b.offset)
                for b in defined.values()]
        assert len(keys) == len(set(keys)), sorted(defined)
    inputs = {v.name: v for v in read_model_description(str(fmus["plant"])).modelVariables if v.causality == "input"}
    for signal in PLANT_INPUTS:
        found = db.get_message_by_name(signal.message).get_signal_by_name(signal.signal)
        if inputs[signal.name].type == "Boolean":  # a 1-bit flag (FMI gives a Boolean no range)
            assert (found.length, found.minimum, found.maximum) == (1, 0, 1), signal
        else:
            assert (float(inputs[signal.name].min), float(inputs[signal.name].max)) == (found.minimum, found.maximum)
    assert [inputs[n].type for n in ("CreepRequest", "BrakeRequest", "P_CL_Cmd")] == ["Boolean", "Boolean", "Real"]


def _held(t: float) -> tuple[float, float, float]:
    return next((P_CL, P_CH, brake) for start, P_CL, P_CH, brake in reversed(SCRIPT) if t >= start)


def _in_process() -> np.ndarray:
    """The plant in this process over the script, each period's outputs in the DBC's units (its CAN edge)."""
    plant = plant_for(load_scenario(), load_params())
    rows = []
    for k in range(round(STOP / STEP) + 1):
        out = plant.outputs()
        values = plant_signals(out, DriverInput(out.t, False, 0.0, 0.0))
        rows.append([values[s.message][s.signal] for s in PLANT_OUTPUTS])
        P_CL, P_CH, brake = _held(k / 100)
        plant.advance(PlantInputs(P_CL_cmd=P_CL * CV.MPA_TO_PA, P_CH_cmd=P_CH * CV.MPA_TO_PA, brake=brake / 100), 10)
    return np.array(rows)


SIMULATE = """
import json, sys
import numpy as np
from fmpy import simulate_fmu
script, names = json.loads(sys.argv[2]), json.loads(sys.argv[3])
rows = []
for i, (t, P_CL, P_CH, brake) in enumerate(script):  # held values: a step at each t (the row before, the row at)
    if i:
        rows.append((t, *rows[-1][1:]))
    rows.append((t, P_CL, P_CH, brake))
rows.append((float(sys.argv[4]), *rows[-1][1:]))
signals = np.array(rows, dtype=[("time", float), ("P_CL_Cmd", float), ("P_CH_Cmd", float), ("BrakePedal", float)])
result = simulate_fmu(sys.argv[1], stop_time=float(sys.argv[4]), step_size=0.01, output_interval=0.01,
                      input=signals, output=names)
print(json.dumps({"t": result["time"].tolist(), "values": [result[n].tolist() for n in names]}))
"""


@pytest.mark.slow
def test_fmpy_reproduces_the_in_process_plant_to_the_last_bit(fmus):
    names = [s.name for s in PLANT_OUTPUTS]
    fmu = run_python(SIMULATE, str(fmus["plant"]), json.dumps(SCRIPT), json.dumps(names), str(STOP))
    expected = _in_process()
    assert len(fmu["t"]) == len(expected) == 301
    got = np.array(fmu["values"]).T
    assert np.array_equal(got, expected), np.abs(got - expected).max(axis=0)
    assert got[:, names.index("P_CH")].max() > 0.5  # the script reached the plant (not two idle plants)
    assert got[-1, names.index("SIM_TRUTH_CL.T_Plate")] > got[0, names.index("SIM_TRUTH_CL.T_Plate")]


ROLLBACK = """
import json, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
md = read_model_description(sys.argv[1])
vr = {v.name: v.valueReference for v in md.modelVariables}
fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(sys.argv[1]), modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName="plant")
fmu.instantiate()
fmu.setReal([vr["init.T_CL"], vr["vehicle.m"]], [150.0, 9000.0])  # parameters: set before initialisation
fmu.setupExperiment(startTime=0.0); fmu.enterInitializationMode(); fmu.exitInitializationMode()
T_start = fmu.getReal([vr["SIM_TRUTH_CL.T_Plate"]])[0]
fmu.setReal([vr["P_CL_Cmd"]], [0.7])
outputs = [vr[v.name] for v in md.modelVariables if v.causality == "output"]

def run(t0, t1):
    for k in range(round(t0 * 100), round(t1 * 100)):
        fmu.doStep(currentCommunicationPoint=k / 100, communicationStepSize=0.01)
    return fmu.getReal(outputs)

run(0.0, 1.0)
state = fmu.serializeFMUstate(fmu.getFMUstate())
first = run(1.0, 2.0)
fmu.setReal([vr["P_CL_Cmd"]], [0.0])  # a different input after the save: restored with the state
fmu.setFMUstate(fmu.deSerializeFMUstate(state))
again = run(1.0, 2.0)
try:
    fmu.doStep(currentCommunicationPoint=2.0, communicationStepSize=0.0005)  # half an internal step
    odd = "accepted"
except Exception as exc:
    odd = str(exc)
print(json.dumps({"first": first, "again": again, "T_start": T_start, "odd": odd}))
"""


@pytest.mark.slow
def test_the_fmu_state_rolls_the_whole_plant_back(fmus):
    result = run_python(ROLLBACK, str(fmus["plant"]))
    assert result["first"] == result["again"]
    assert result["T_start"] == 150.0  # the parameter set before initialisation is the plant's
    assert result["odd"] != "accepted"  # a step that is no whole number of internal steps fails
