"""The FMUs dsg-hil writes keep their slave module's namespace whole (:func:`dsg_hil.fmi.slave.balance_namespace`):
PythonFMU's binary releases a reference to it it never took, once per instance, which crashed the host's Python at
its end ("corrupted double-linked list") and made a second instance in a process fail. Counted here: instances
neither take nor release a reference to it; several, at once and one after another, instantiate in one process,
which then ends through Python's own shutdown. A PythonFMU FMU written elsewhere, without that call, is made good
by the host (:func:`dsg_hil.fmi.host.instantiate`) when dsg-hil runs it."""

from __future__ import annotations

import sys
from pathlib import Path

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


@pytest.mark.slow
@pytest.mark.parametrize("model", ["plant", "tcu"])
def test_instances_keep_the_slave_module_s_namespace_and_the_process_ends_cleanly(fmus, model):
    counts = run_python(COUNT, str(fmus[model]))["counts"]  # run_python: exit status 0, through Python's shutdown
    assert len(counts) == 7
    assert set(counts) == {counts[0]}, f"references to the slave module's namespace, each step: {counts}"


@pytest.fixture(scope="module")
def user_fmu(tmp_path_factory) -> Path:
    """ecu-stub's controller written as an FMU by PythonFMU's builder alone, as a user writes a controller in
    Python: its slave module does not call balance_namespace."""
    from pythonfmu import FmuBuilder

    folder = tmp_path_factory.mktemp("user_fmu")
    script = folder / "src" / "user_tcu.py"
    script.parent.mkdir()
    script.write_text("from dsg_hil.fmi.tcu_slave import TcuSlave\n\n\nclass user_tcu(TcuSlave):\n    pass\n",
                      encoding="utf-8")
    try:
        return Path(FmuBuilder.build_FMU(script, dest=folder / "user_tcu.fmu"))
    finally:  # the builder imports the script as a top-level module, from its folder
        sys.modules.pop("user_tcu", None)
        if str(script.parent) in sys.path:
            sys.path.remove(str(script.parent))


AROUND = """
import gc, json, os, sys
from fmpy import extract

path, how = sys.argv[1], sys.argv[2]
unzipped = str(extract(path))
resources = os.path.join(unzipped, "resources")
sys.path.insert(0, resources)
namespace = __import__("user_tcu").__dict__
gc.collect()
before = sys.getrefcount(namespace)
if how == "fmpy":  # as FMPy alone instantiates it
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave
    md = read_model_description(path)
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="tcu")
    fmu.instantiate()
else:  # as 'dsg-hil run --controller' does
    from dsg_hil.fmi.controller import FmuController, open_controller
    controller = open_controller(path)
    FmuController(controller)
gc.collect()
print(json.dumps({"before": before, "after": sys.getrefcount(namespace)}))
sys.stdout.flush()
if how == "fmpy":
    os._exit(0)  # the namespace short of a reference: Python's shutdown would crash
controller.close()
"""


@pytest.mark.slow
def test_a_pythonfmu_fmu_of_a_user_is_made_good_by_the_host_and_not_by_fmpy_alone(user_fmu):
    fmpy = run_python(AROUND, str(user_fmu), "fmpy")
    assert fmpy["after"] == fmpy["before"] - 1, f"PythonFMU's binary no longer releases the reference: {fmpy}"
    host = run_python(AROUND, str(user_fmu), "dsg_hil")  # and the process ends through Python's own shutdown
    assert host["after"] == host["before"], host
