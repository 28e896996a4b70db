"""Instantiating an FMU in this process through FMPy, kept safe from PythonFMU's two faults at a host's end.

PythonFMU's binary (0.6.4 to 0.7.0) releases, per instance, a reference to its slave module's namespace that it
never took (:func:`dsg_hil.fmi.slave.balance_namespace`, which the FMUs ``dsg-hil fmu export`` writes call). A
PythonFMU FMU written elsewhere (a user's controller in Python) lacks that call: the host's Python then crashes
at its end, after the run ("corrupted double-linked list"). :func:`instantiate` counts the references to the slave
module's namespace around ``fmi2Instantiate`` and gives back what went missing, so such an FMU runs here too.
And the binary writes to freed memory when the process exits (:func:`end_binary_state_at_exit`, which the slaves
of dsg-hil's FMUs call themselves): :func:`instantiate` has any FMU's PythonFMU binary's state ended at Python's
exit, before that. Any other FMU (no ``resources/slavemodule.txt``) is instantiated as it is.
"""

from __future__ import annotations

import atexit
import ctypes
import gc
import importlib
import os
import sys
from pathlib import Path
from typing import Any

__all__ = ["KINDS", "Ref", "end_binary_state_at_exit", "get_values", "instantiate", "set_values"]

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
    takes from its slave module's namespace given back, its binary's state ended at Python's exit
    (:func:`end_binary_state_at_exit`)."""
    namespace = _slave_namespace(Path(unzipped) / "resources")
    try:
        if namespace is None:
            fmu.instantiate()
            return
        gc.collect()  # what the binary's second run of the module leaves behind is collected before each count
        before = sys.getrefcount(namespace)
        fmu.instantiate()
    finally:  # the binary made its state before the instance: an instantiation that failed leaves it too
        end_binary_state_at_exit(unzipped)
    gc.collect()
    for _ in range(before - sys.getrefcount(namespace)):
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(namespace))


_ENDED_AT_EXIT: set[str] = set()  # the PythonFMU binaries whose state this process ends at its exit (their paths)


def end_binary_state_at_exit(fmu_root: str | Path) -> list[str]:
    """Have Python end, at this process's exit, the state of each PythonFMU binary of the FMU extracted to
    ``fmu_root`` that this process has loaded (``binaries/*/*.so``): once per binary, by its own
    ``finalizePythonInterpreter``, from an :mod:`atexit` handler. Returns those binaries' paths; none on a system
    other than Linux.

    PythonFMU's binary (0.6.4 to 0.7.0 and its git main, ``PySlaveInstance.cpp``) keeps a ``PyState`` in a static
    ``shared_ptr``, made at the first ``fmi2Instantiate``, and ends it twice when the process exits: the C
    library's exit handlers run the ``shared_ptr``'s destructor, which deletes it; then ``_dl_fini`` runs the
    binary's ``__attribute__((destructor))``, which assigns ``nullptr`` to that destroyed ``shared_ptr`` and so
    decrements the use count in the freed block: a write to freed memory. Where the allocator has reused or binned
    that block, the heap is corrupt and the host dies after its last line ("corrupted double-linked list",
    "free(): corrupted unsorted chunks", a segmentation fault), whether it freed its instances or not: ``dlclose``
    never unloads the binary (its ``std::regex`` code has ``STB_GNU_UNIQUE`` symbols), which would have run the two
    in the safe order. Python's :mod:`atexit` handlers run before the C library's: ``finalizePythonInterpreter``
    there deletes the state while it is alive, and both steps at the exit find a null pointer. In a Python host the
    state owns nothing (the interpreter was there before it, its thread has ended). In a host that is no Python
    program the state's destructor finalizes the embedded interpreter at the exit, which runs this handler inside
    it: the pointer is null before ``_dl_fini`` reads it."""
    if not sys.platform.startswith("linux"):  # DllMain on Windows ends the state once, in the right order
        return []
    ended = []
    for path in sorted(Path(fmu_root).glob("binaries/*/*.so")):
        try:  # the loaded library, never a second copy: RTLD_NOLOAD (and one of LAZY, NOW, as dlopen asks)
            library = ctypes.CDLL(str(path), mode=os.RTLD_NOLOAD | os.RTLD_LAZY)
            finalize = library.finalizePythonInterpreter
        except (OSError, AttributeError):  # not loaded in this process, or not PythonFMU's binary
            continue
        key = str(path.resolve())
        if key not in _ENDED_AT_EXIT:
            _ENDED_AT_EXIT.add(key)
            finalize.argtypes, finalize.restype = [], None
            atexit.register(finalize)
        ended.append(key)
    return ended


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
