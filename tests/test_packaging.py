"""What the package ships: the DBC as a real resource identical to dbc/, py.typed, one version, the wheel."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from importlib import metadata, resources
from pathlib import Path

import pytest

import dsg_hil
from dsg_hil.protocol.codec import DEFAULT_DBC
from dsg_hil.e2e.vcan import ENV_REQUIRE

ROOT = Path(__file__).resolve().parents[1]  # the checkout (or unpacked sdist) these tests came from
TOP_DBC = ROOT / "dbc" / "dsg_hil.dbc"


def test_dbc_resource_is_a_real_file_loadable_as_a_resource():
    text = DEFAULT_DBC.read_text(encoding="utf-8")
    assert text.startswith("VERSION") and "BO_ 512 TCU_CMD" in text  # not a 21-byte symlink stand-in
    assert not Path(str(DEFAULT_DBC)).is_symlink()


@pytest.mark.skipif(not TOP_DBC.exists(), reason="dbc/dsg_hil.dbc is in the source tree only (tests run from a "
                                                 "copy outside it)")
def test_dbc_resource_is_identical_to_the_top_level_dbc():
    assert DEFAULT_DBC.read_bytes() == TOP_DBC.read_bytes(), \
        "dsg_hil/data/dsg_hil.dbc and dbc/dsg_hil.dbc differ: copy one onto the other"


def test_typed_packages():
    for package in ("dsg_hil", "ecu_stub"):
        assert (resources.files(package) / "py.typed").is_file(), package


def test_version_is_single_sourced():
    assert metadata.version("dsg-hil") == dsg_hil.__version__
    pyproject = ROOT / "pyproject.toml"
    if pyproject.exists():
        text = pyproject.read_text(encoding="utf-8")
        assert 'dynamic = ["version"]' in text and 'version = { attr = "dsg_hil.__version__" }' in text


def test_marker_expressions_do_not_bring_back_the_vcan_tests():
    """tests/conftest.py deselects the vcan tests for any -m that does not name vcan (not a configured -m)."""
    e2e = str(resources.files("dsg_hil.e2e"))
    args = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
            str(Path(__file__).parent / "sim" / "test_scenario.py"), e2e]
    env = {k: v for k, v in os.environ.items() if k != ENV_REQUIRE}
    for expr in ("not slow", "slow or not slow", "vcan"):
        out = subprocess.run([*args, "-m", expr], capture_output=True, text=True, env=env).stdout
        e2e_ids = [line for line in out.splitlines() if "test_end_to_end.py::" in line]
        assert bool(e2e_ids) == (expr == "vcan"), out
        assert (expr == "vcan") or "deselected" in out, out


@pytest.mark.slow
def test_wheel_ships_the_dbc_typing_license_and_extras(tmp_path):
    if not (ROOT / "pyproject.toml").exists():
        pytest.skip("needs the source tree")
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(ROOT)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    (wheel,) = tmp_path.glob("dsg_hil-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        assert zf.read("dsg_hil/data/dsg_hil.dbc") == TOP_DBC.read_bytes()
        info = f"dsg_hil-{dsg_hil.__version__}.dist-info"
        meta = zf.read(f"{info}/METADATA").decode()
    assert {"dsg_hil/py.typed", "ecu_stub/py.typed", "dsg_hil/data/params.toml", "dsg_hil/data/creep.toml",
            "dsg_hil/data/sweeps/safety.toml", "dsg_hil/sweep/engine.py",
            "dsg_hil/e2e/conftest.py", "dsg_hil/e2e/test_end_to_end.py", f"{info}/licenses/LICENSE"} <= names
    assert not any(name.startswith("tests/") for name in names)
    assert "License-Expression: MIT" in meta and f"Version: {dsg_hil.__version__}" in meta
    requires = [line for line in meta.splitlines() if line.startswith("Requires-Dist: matplotlib")]
    assert "Provides-Extra: plots" in meta and requires and all('extra == "plots"' in r for r in requires)
