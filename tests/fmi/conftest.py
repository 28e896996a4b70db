"""The FMUs of the FMI tests, written once per session, and a way to run FMU code in a process of its own.

One FMU instance per process: an FMU written by PythonFMU cannot be instantiated a second time in a process (it
fails with "Failed to instantiate model", even after the first instance was freed; reported against PythonFMU
for several instances too). Everything that instantiates an FMU therefore runs in a fresh Python process
(:func:`run_python`); exporting and validating only read and write files, and run here.
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


# The process ends without Python's clean-up: once, after FMPy had freed a PythonFMU instance, the interpreter's
# shutdown aborted ("corrupted double-linked list", status -6) with the results already printed (not seen again).
_EXIT = "\nimport os as _os, sys as _sys\n_sys.stdout.flush()\n_os._exit(0)\n"


def run_python(code: str, *args: str, timeout: float = 300.0) -> dict:
    """Run ``code`` (with ``sys.argv[1:] = args``) in a fresh Python; it prints one JSON object last: returned."""
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code) + _EXIT, *args], capture_output=True,
                          text=True, timeout=timeout)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])
