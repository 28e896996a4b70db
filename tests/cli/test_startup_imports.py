"""Start-up: a command's ``--help`` (and importing the command line) loads none of the heavy libraries the commands
need only when they run (numpy, scipy, matplotlib, cantools), so it starts at once. What is imported is checked,
in a fresh interpreter, never how long it takes."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import pytest

from dsg_hil.cli import COMMANDS

HEAVY = ("numpy", "scipy", "matplotlib", "cantools")
# python-can imports asammdf, and with it numpy, as it is imported, if asammdf is there (the mf4 extra): then numpy
# comes with python-can, which a command's options need; without the extra, not
WITH_PYTHON_CAN = {"numpy"} if importlib.util.find_spec("asammdf") else set()


def imported_after(code: str) -> list[str]:
    """The heavy top-level packages in ``sys.modules`` after running ``code`` (a SystemExit of --help is fine)."""
    probe = (f"import sys\ntry:\n    {code}\nexcept SystemExit:\n    pass\n"
             f"print(' '.join(m for m in {HEAVY + ('can',)!r} if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True)
    return proc.stdout.split()


def test_importing_the_command_line_loads_no_heavy_library_nor_python_can():
    assert imported_after("import dsg_hil.cli, dsg_hil.common.errors, dsg_hil.protocol") == []


@pytest.mark.parametrize("command", [[], *([name] for name in COMMANDS)], ids=lambda c: " ".join(c) or "top")
def test_help_of_every_command_loads_no_heavy_library(command):
    loaded = set(imported_after(f"from dsg_hil.cli import main; main({[*command, '--help']!r})"))
    assert loaded & set(HEAVY) - WITH_PYTHON_CAN == set()


def test_ecu_stub_help_loads_no_heavy_library():
    loaded = set(imported_after("from ecu_stub.cli import main; main(['--help'])"))
    assert loaded & set(HEAVY) - WITH_PYTHON_CAN == set()


def test_the_heavy_libraries_are_there_once_a_codec_is_used():
    """The probe can see an import (so the assertions above could fail)."""
    assert "cantools" in imported_after("from dsg_hil.protocol import Codec")
