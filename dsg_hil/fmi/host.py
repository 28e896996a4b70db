"""Instantiating an FMU in this process through FMPy, kept safe from PythonFMU's reference fault.

PythonFMU's binary (0.6.4 to 0.7.0) releases, per instance, a reference to its slave module's namespace that it
never took (:func:`dsg_hil.fmi.slave.balance_namespace`, which the FMUs ``dsg-hil fmu export`` writes call). A
PythonFMU FMU written elsewhere (a user's controller in Python) lacks that call: the host's Python then crashes
at its end, after the run ("corrupted double-linked list"). :func:`instantiate` counts the references to the slave
module's namespace around ``fmi2Instantiate`` and gives back what went missing, so such an FMU runs here too.
Any other FMU (no ``resources/slavemodule.txt``) is instantiated as it is.
"""

from __future__ import annotations

import ctypes
import gc
import importlib
import sys
from pathlib import Path
from typing import Any

__all__ = ["KINDS", "Ref", "get_values", "instantiate", "set_values"]

KINDS = ("Real", "Integer", "Boolean")  # the FMI 2.0 types a signal's variable may have (signals.kind_of)
Ref = tuple[str, int]  # a variable's (FMI type, value reference)


def get_values(fmu: Any, refs: list[Ref]) -> list[float]:
    """The values of the variables ``refs`` of an FMPy ``FMU2Slave``, whatever their types, as floats (a Boolean:
    0.0 or 1.0), in the order of ``refs``."""
    values = [0.0] * len(refs)
    for kind, read in (("Real", fmu.getReal), ("Integer", fmu.getInteger), ("Boolean", fmu.getBoolean)):
        at = [i for i, (k, _) in enumerate(refs) if k == kind]
        if at:
            for i, value in zip(at, read([refs[i][1] for i in at])):
                values[i] = float(value)
    return values


def set_values(fmu: Any, refs: list[Ref], values: list[float]) -> None:
    """Set the variables ``refs`` to ``values`` (a whole number for an Integer, >= 0.5 true for a Boolean)."""
    for kind, write, convert in (("Real", fmu.setReal, float), ("Integer", fmu.setInteger, round),
                                 ("Boolean", fmu.setBoolean, lambda v: v >= 0.5)):
        at = [i for i, (k, _) in enumerate(refs) if k == kind]
        if at:
            write([refs[i][1] for i in at], [convert(values[i]) for i in at])


def instantiate(fmu: Any, unzipped: str | Path) -> None:
    """``fmu.instantiate()`` (an FMPy ``FMU2Slave`` extracted to ``unzipped``), the references a PythonFMU binary
    takes from its slave module's namespace given back."""
    namespace = _slave_namespace(Path(unzipped) / "resources")
    if namespace is None:
        fmu.instantiate()
        return
    gc.collect()  # what the binary's second run of the module leaves behind is collected before each count
    before = sys.getrefcount(namespace)
    fmu.instantiate()
    gc.collect()
    for _ in range(before - sys.getrefcount(namespace)):
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(namespace))


def _slave_namespace(resources: Path) -> dict[str, Any] | None:
    """The namespace of a PythonFMU FMU's slave module (``resources/slavemodule.txt`` names it), imported from the
    FMU's resources as its binary imports it; None for another FMU, or one whose module does not import here (its
    binary then reports that itself)."""
    marker = resources / "slavemodule.txt"
    if not marker.is_file():
        return None
    words = marker.read_text(encoding="utf-8").split()  # its first line: the module's name
    if not words:
        return None
    if str(resources) not in sys.path:
        sys.path.insert(0, str(resources))  # where the binary puts it
    try:
        module = importlib.import_module(words[0])
    except Exception:  # noqa: BLE001 - the FMU's own code: its binary reports the error on instantiating
        return None
    return module.__dict__
