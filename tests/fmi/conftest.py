"""The FMUs of the FMI tests, written once per session, and a way to run FMU code in a process of its own.

Everything that instantiates an FMU runs in a fresh Python process (:func:`run_python`), which ends through
Python's own shutdown: the FMUs' slave modules are imported from the FMU's resources as top-level modules, one
name per model, so two FMUs of one model in this process would share the first one's; and an unbalanced
reference (:func:`dsg_hil.fmi.slave.balance_namespace`) shows as a crash at the process's end. Exporting and
validating only read and write files, and run here.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytest.importorskip("pythonfmu")
pytest.importorskip("fmpy")


@pytest.fixture(scope="session")
def fmus(tmp_path_factory) -> dict[str, Path]:
    """The plant FMU and ecu-stub's controller as an FMU, exported as 'dsg-hil fmu export' does."""
    from dsg_hil.fmi.export import export_fmu

    folder = tmp_path_factory.mktemp("fmus")
    return {model: export_fmu(folder / f"{model}.fmu", model=model) for model in ("plant", "tcu")}


def run_python(code: str, *args: str, timeout: float = 300.0, env: dict[str, str] | None = None) -> dict:
    """Run ``code`` (with ``sys.argv[1:] = args``) in a fresh Python (``env``: its environment, default this
    one's); it prints one JSON object last: returned."""
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code), *args], capture_output=True,
                          text=True, timeout=timeout, env=env)
    assert done.returncode == 0, f"exit status {done.returncode}; stderr: {done.stderr[-3000:]}"
    return json.loads(done.stdout.strip().splitlines()[-1])


# The start of a script that opens FMU instances through FMPy's FMU2Slave, each with its log collected:
# open_instance(path, name, logging_on=True) -> (fmu, {variable name: value reference},
#                                                log: [(status label, message), ...])
OPEN_INSTANCE = """
import json, math, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import (FMU2Slave, calloc, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, free)

LABELS = ["OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING"]
_keep = []

def open_instance(path, name, logging_on=True):
    md = read_model_description(path)
    log = []
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(
        lambda c, instance, status, category, message: log.append((LABELS[status], message.decode("utf-8"))))
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    _keep.append(callbacks)
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=name)
    fmu.instantiate(callbacks=callbacks, loggingOn=logging_on)  # the FMU passes messages on with logging on only
    return fmu, {v.name: v.valueReference for v in md.modelVariables}, log
"""
