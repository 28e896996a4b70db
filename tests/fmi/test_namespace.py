"""The FMUs dsg-hil writes keep their slave module's namespace whole (:func:`dsg_hil.fmi.slave.balance_namespace`):
PythonFMU's binary releases a reference to it it never took, once per instance, which crashed the host's Python at
its end ("corrupted double-linked list") and made a second instance in a process fail. Counted here: instances
neither take nor release a reference to it; several, at once and one after another, instantiate in one process,
which then ends through Python's own shutdown."""

from __future__ import annotations

import pytest

from .conftest import run_python

COUNT = """
import gc, json, os, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

path = sys.argv[1]
md = read_model_description(path)
unzipped = str(extract(path))
resources = os.path.join(unzipped, "resources")
with open(os.path.join(resources, "slavemodule.txt"), encoding="utf-8") as f:
    module = f.readline().strip()  # the module PythonFMU's binary imports
sys.path.insert(0, resources)
namespace = __import__(module).__dict__
counts = [sys.getrefcount(namespace)]


def started(name):
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=name)
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.01)
    gc.collect()
    counts.append(sys.getrefcount(namespace))
    return fmu


def freed(fmu):
    fmu.terminate()
    fmu.freeInstance()
    gc.collect()
    counts.append(sys.getrefcount(namespace))


both = [started("a"), started("b")]  # two at once
for fmu in both:
    freed(fmu)
freed(started("c"))  # and one more after they were freed
print(json.dumps({"counts": counts}))
"""


@pytest.mark.parametrize("model", ["plant", "tcu"])
def test_instances_keep_the_slave_module_s_namespace_and_the_process_ends_cleanly(fmus, model):
    counts = run_python(COUNT, str(fmus[model]))["counts"]  # run_python: exit status 0, through Python's shutdown
    assert len(counts) == 7
    assert set(counts) == {counts[0]}, f"references to the slave module's namespace, each step: {counts}"
