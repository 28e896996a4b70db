"""Small spaces and a way to run ``dsg-hil sweep`` for the sweep's tests (short runs: 3-4 simulated s)."""

from __future__ import annotations

import os
import subprocess
import sys
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


def sweep_env() -> dict[str, str]:
    """The environment of a sweep process or Dask worker: the tests importable (the planted controller)."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}


def sweep(*args: str, timeout: float = 600.0) -> subprocess.CompletedProcess[str]:
    """``dsg-hil sweep ARGS`` in a fresh process."""
    return subprocess.run([sys.executable, "-m", "dsg_hil", "sweep", *args], capture_output=True, text=True,
                          timeout=timeout, env=sweep_env(), cwd=REPO)
