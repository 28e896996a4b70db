"""ecu_stub knows the plant only through the DBC: it imports nothing from dsg_hil but the protocol layer and the
shared kernel (dsg_hil.common: errors, files, units)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import ecu_stub
from dsg_hil.common.build import GROUP

ECU_STUB = Path(ecu_stub.__file__).resolve().parent  # the sources under test, in a checkout or installed


def imported_modules(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
    return names


SHARED = ("dsg_hil.protocol", "dsg_hil.common")


def shared(name: str) -> bool:
    return name in ("dsg_hil", *SHARED) or name.startswith(tuple(f"{p}." for p in SHARED))


def test_sources_import_only_the_protocol_layer_and_common():
    files = sorted(ECU_STUB.glob("*.py"))
    assert len(files) >= 6
    for path in files:
        for name in imported_modules(path):
            if name == "dsg_hil" or name.startswith("dsg_hil."):
                assert name != "dsg_hil" and shared(name), f"{path.name}: {name}"


def test_loading_ecu_stub_loads_no_plant_module():
    """No plant module is imported. The compiled build loads mypyc's one library of all compiled modules (GROUP's:
    the plant's compiled runner's machine code with the TCU's), which runs none of the plant: it is not a module."""
    code = ("import sys, ecu_stub.cli, ecu_stub.runner, ecu_stub.controller;"
            "print(sorted(m for m in sys.modules if m.startswith('dsg_hil')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    loaded = eval(out)  # noqa: S307 - our own printed list
    assert "dsg_hil.protocol" in loaded
    assert all(shared(m) for m in loaded if m != f"{GROUP}__mypyc"), loaded
