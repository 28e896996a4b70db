"""Small spaces and a way to run ``dsg-hil sweep`` for the sweep's tests (short runs: 3-4 simulated s)."""

from __future__ import annotations

import functools
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

SMALL = """
name = "small"
seed = 7
n = 12
duration_s = 3.0
[inputs]
grade_rad = {uniform = [0.0, 0.2]}
"initial.T_clutch_c" = {uniform = [80, 200]}
"initial.T_oil_c" = {normal = [90, 5]}
"params.vehicle.m" = {uniform = [6000, 9000]}
"driver.behaviour" = {choice = ["creep", "brake_drag", "stop_and_go", "creep_toggles"]}
"driver.desired_speed_mps" = {uniform = [0.05, 0.4]}
"driver.brake_s" = 0.5
"driver.drag_level" = {uniform = [0.0, 0.1]}
"driver.drag_onset_s" = {uniform = [0.5, 2.5]}
"driver.drag_duration_s" = 1.0
"driver.creep_s" = 1.0
"driver.stop_s" = 0.5
"driver.toggle_s" = 0.7
"""


@pytest.fixture
def small_space(tmp_path: Path) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(SMALL, encoding="utf-8")
    return path


@functools.cache
def _tests_only() -> str:
    """A directory holding nothing but a link to this checkout's ``tests`` package: on PYTHONPATH it makes the tests
    importable (the planted controllers, ``tests.sweep.unsafe:Slipper``) without the checkout's ``dsg_hil``
    shadowing the installed one (the compiled build under test)."""
    where = Path(tempfile.mkdtemp(prefix="dsg-hil-tests-path-"))
    (where / "tests").symlink_to(REPO / "tests", target_is_directory=True)
    return str(where)


def sweep_env() -> dict[str, str]:
    """The environment of a sweep process or Dask worker: the tests importable (the planted controller), the
    package the installed one."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([_tests_only(), os.environ.get("PYTHONPATH", "")])}


def sweep(*args: str, timeout: float = 600.0) -> subprocess.CompletedProcess[str]:
    """``dsg-hil sweep ARGS`` in a fresh process."""
    return subprocess.run([sys.executable, "-m", "dsg_hil", "sweep", *args], capture_output=True, text=True,
                          timeout=timeout, env=sweep_env(), cwd=REPO)
