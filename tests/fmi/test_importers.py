"""The FMUs under a second importer from the package index: libcosim (DNV's C++ co-simulation library, through
libcosimpy) runs the plant FMU as FMPy and the in-process plant do, and the plant FMU with ecu-stub's controller
FMU as FMPy does, bit for bit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dsg_hil.fmi.signals import PLANT_OUTPUTS

from .conftest import run_python
from .test_plant_fmu import SCRIPT, SIMULATE, STOP, _in_process

pytest.importorskip("libcosimpy")

LIBCOSIM = """
import json, sys
from fmpy import read_model_description
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimManipulator import CosimManipulator
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave

log_output_level(CosimLogLevel.ERROR)  # libcosim logs on stdout: the JSON line must be the last
path, script, names, stop = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3]), float(sys.argv[4])
vr = {v.name: v.valueReference for v in read_model_description(path).modelVariables}
execution = CosimExecution.from_step_size(step_size=10_000_000)  # ns: 10 ms
plant = execution.add_local_slave(local_slave=CosimLocalSlave(fmu_path=path, instance_name="plant"))
manipulator, observer = CosimManipulator.create_override(), CosimObserver.create_last_value()
execution.add_manipulator(manipulator=manipulator)
execution.add_observer(observer=observer)
inputs, outputs = [vr["P_CL_Cmd"], vr["P_CH_Cmd"], vr["BrakePedal"]], [vr[n] for n in names]
rows = []
for k in range(round(stop * 100)):  # each step from k/100 with the inputs held from there: the outputs at its end
    manipulator.slave_real_values(plant, inputs, next(row[1:] for row in reversed(script) if k >= round(row[0] * 100)))
    execution.step()  # the first one initialises the FMU, then steps
    rows.append(observer.last_real_values(plant, outputs))
print(json.dumps({"rows": rows}))
"""


@pytest.mark.slow
def test_libcosim_and_fmpy_run_the_plant_fmu_to_the_same_bit(fmus):
    names = [s.name for s in PLANT_OUTPUTS]
    args = (str(fmus["plant"]), json.dumps(SCRIPT), json.dumps(names), str(STOP))
    libcosim = np.array(run_python(LIBCOSIM, *args)["rows"])
    fmpy = np.array(run_python(SIMULATE, *args)["values"]).T
    assert libcosim.shape == (300, 24) and fmpy.shape == (301, 24)
    assert np.array_equal(libcosim, fmpy[1:]), np.abs(libcosim - fmpy[1:]).max(axis=0)
    assert np.array_equal(libcosim, _in_process()[1:])
    assert libcosim[:, names.index("P_CH")].max() > 0.5  # the script reached the plant under libcosim too


# The plant FMU and the TCU FMU connected by name, the scenario's driver given to both, each step from t with the
# other's outputs at t (libcosim's fixed-step algorithm; by hand in FMPy): the plant's trajectory
PAIR = """
import json, sys
from fmpy import read_model_description
from dsg_hil.fmi.signals import PLANT_INPUTS, PLANT_OUTPUTS
from dsg_hil.sim.scenario import load_scenario

plant_path, tcu_path, importer, n = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
P = {v.name: (v.type, v.valueReference) for v in read_model_description(plant_path).modelVariables}
C = {v.name: (v.type, v.valueReference) for v in read_model_description(tcu_path).modelVariables}
reads = [s.name for s in PLANT_OUTPUTS if s.name in C]
commands = [s.name for s in PLANT_INPUTS if s.name in C and s.message != "DRIVER"]
watch = ["VehicleSpeed", "SIM_TRUTH_CL.T_Plate", "ClutchInputSpeed", "P_CL"]
scenario = load_scenario()

def driver(k):
    d = scenario.driver_at(k / 100)
    return {"CreepRequest": float(d.creep_request), "BrakePedal": d.brake * 100.0,
            "DesiredCreepSpeed": d.desired_speed_mps}

rows = []
if importer == "fmpy":
    from dsg_hil.fmi.cosim import open_fmu
    from dsg_hil.fmi.host import get_values, set_values
    plant, _ = open_fmu(plant_path, "plant")
    tcu, _ = open_fmu(tcu_path, "tcu")
    for k in range(n):
        d = driver(k)
        to_tcu, to_plant = get_values(plant, [P[x] for x in reads]), get_values(tcu, [C[x] for x in commands])
        set_values(tcu, [C[x] for x in reads] + [C[x] for x in d], to_tcu + list(d.values()))
        set_values(plant, [P[x] for x in commands] + [P[x] for x in d], to_plant + list(d.values()))
        tcu.doStep(k / 100, 0.01)
        plant.doStep(k / 100, 0.01)
        rows.append(get_values(plant, [P[x] for x in watch]))
else:
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_step_size(step_size=10_000_000)
    ip = execution.add_local_slave(local_slave=CosimLocalSlave(fmu_path=plant_path, instance_name="plant"))
    it = execution.add_local_slave(local_slave=CosimLocalSlave(fmu_path=tcu_path, instance_name="tcu"))
    manipulator, observer = CosimManipulator.create_override(), CosimObserver.create_last_value()
    execution.add_manipulator(manipulator=manipulator)
    execution.add_observer(observer=observer)
    connect = {"Real": execution.connect_real_variables, "Integer": execution.connect_integer_variables,
               "Boolean": execution.connect_boolean_variables}
    for x in reads:
        connect[P[x][0]](ip, P[x][1], it, C[x][1])
    for x in commands:  # the pressures, the deceleration (Reals) and BrakeRequest (a Boolean)
        connect[C[x][0]](it, C[x][1], ip, P[x][1])
    for k in range(n):
        d = driver(k)
        for index, refs in ((ip, P), (it, C)):
            manipulator.slave_real_values(index, [refs["BrakePedal"][1], refs["DesiredCreepSpeed"][1]],
                                          [d["BrakePedal"], d["DesiredCreepSpeed"]])
            manipulator.slave_boolean_values(index, [refs["CreepRequest"][1]], [d["CreepRequest"] >= 0.5])
        execution.step()
        rows.append(observer.last_real_values(ip, [P[x][1] for x in watch]))
print(json.dumps({"rows": rows}))
"""


@pytest.mark.slow
def test_libcosim_and_fmpy_co_simulate_the_plant_and_tcu_fmus_to_the_same_bit(fmus):
    args = (str(fmus["plant"]), str(fmus["tcu"]))
    fmpy = np.array(run_python(PAIR, *args, "fmpy", "300")["rows"])
    libcosim = np.array(run_python(PAIR, *args, "libcosim", "300")["rows"])
    assert fmpy.shape == libcosim.shape == (300, 4)
    assert np.array_equal(libcosim, fmpy), np.abs(libcosim - fmpy).max(axis=0)
    # a creep, not two idle models: the TCU's pressure reached CL, the plate heated, the vehicle moves
    assert fmpy[:, 3].max() > 0.1 and fmpy[-1, 1] - fmpy[0, 1] > 10.0 and fmpy[-1, 0] > 0.05
