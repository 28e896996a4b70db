"""The plant FMU under a second importer from the package index: libcosim (DNV's C++ co-simulation library,
through libcosimpy) gives FMPy's trajectory and the in-process plant's, bit for bit."""

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


def test_libcosim_and_fmpy_run_the_plant_fmu_to_the_same_bit(fmus):
    names = [s.name for s in PLANT_OUTPUTS]
    args = (str(fmus["plant"]), json.dumps(SCRIPT), json.dumps(names), str(STOP))
    libcosim = np.array(run_python(LIBCOSIM, *args)["rows"])
    fmpy = np.array(run_python(SIMULATE, *args)["values"]).T
    assert libcosim.shape == (300, 24) and fmpy.shape == (301, 24)
    assert np.array_equal(libcosim, fmpy[1:]), np.abs(libcosim - fmpy[1:]).max(axis=0)
    assert np.array_equal(libcosim, _in_process()[1:])
    assert libcosim[:, names.index("P_CH")].max() > 0.5  # the script reached the plant under libcosim too
