"""Every documented kind of controller drives the plant through the build that is installed: the bundled ecu-stub,
a CreepController with another calibration, a Python object with ``step()``, a controller FMU, a command line and a
sweep's ``module:factory``. The regular install compiles the runners (mypyc checks declared types at run time), so
each kind crosses a typed door there (ecu_stub.interface.TcuController, dsg_hil.testing.Controller, ...): CI runs
this on the compiled build, where a door typed by a concrete class once refused the controller FMU."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from dsg_hil.sim.run import RunConfig, open_run
from dsg_hil.sweep.controllers import config_for

from ecu_stub.calibration import load_calibration
from ecu_stub.controller import CreepController
from ecu_stub.interface import TcuController

SECONDS = 2.0  # the default scenario's driver asks to creep at 1 s
TICKS = round(SECONDS / 0.01)  # TCU_CMD's cycle (the DBC): one command per lock-step tick


def assert_commands_flowed(summary: Mapping[str, Any]) -> None:
    """The plant took a command from the controller at every tick, none rejected, none missed, no fallback."""
    frames = summary["frames"]
    cmd = frames["by_message"]["TCU_CMD"]
    assert cmd["taken"] == TICKS and not cmd["rejected"], cmd
    assert frames["rejected"] == 0 and frames["unanswered_ticks"] == 0, frames
    assert summary["sim_time_s"] == pytest.approx(SECONDS)


def dsg_hil(*argv: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "dsg_hil", *argv], cwd=cwd, capture_output=True, text=True,
                          timeout=600)


class Hold:
    """A controller with ``step()``: CL at a fixed pressure, CH open (the plant must see that pressure)."""

    P_CL_MPA = 0.35

    def step(self, t: float, inputs: Mapping[str, Mapping[str, float]]) -> Mapping[str, float]:
        return {"P_CL_Cmd": self.P_CL_MPA, "P_CH_Cmd": 0.0}


@pytest.mark.slow
def test_the_bundled_ecu_stub_through_dsg_hil_run(tmp_path):
    done = dsg_hil("run", "-q", "--duration", str(SECONDS), "--summary", "s.json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert_commands_flowed(json.loads((tmp_path / "s.json").read_text()))


def test_a_creep_controller_with_another_calibration_through_the_fixture(dsg_hil_run):
    shipped = load_calibration()
    other = replace(shipped, launch=replace(shipped.launch, F_prefill_n=shipped.launch.F_prefill_n * 0.5))
    assert isinstance(CreepController(other), TcuController)
    runs = {name: dsg_hil_run(CreepController(cal), duration=SECONDS, log=None)
            for name, cal in (("shipped", shipped), ("other", other))}
    for run in runs.values():
        assert_commands_flowed(run.summary)
    commands = {name: [bytes(m.data) for m in run.frames if m.arbitration_id == 0x200]
                for name, run in runs.items()}
    assert len(commands["other"]) == TICKS and commands["other"] != commands["shipped"]  # its calibration ran


def test_a_python_object_with_step_through_the_fixture(dsg_hil_run):
    run = dsg_hil_run(Hold(), duration=SECONDS, log=None)
    assert_commands_flowed(run.summary)
    assert run.signals["TCU_CMD.P_CL_Cmd"][-1] == pytest.approx(Hold.P_CL_MPA, abs=0.01)
    assert run.truth["P_CL"].max() > 0.5 * Hold.P_CL_MPA * 1e6  # the plant's pressure followed it [Pa]


@pytest.mark.slow
def test_a_command_line_through_the_fixture(dsg_hil_run):
    run = dsg_hil_run([sys.executable, "-m", "ecu_stub", "{bus_args}"], duration=SECONDS, log=None)
    assert_commands_flowed(run.summary)


@pytest.mark.slow
def test_a_controller_fmu_through_dsg_hil_run(tmp_path):
    pytest.importorskip("fmpy", reason="the fmi extra (in the test extra): pip install '.[fmi]'")
    done = dsg_hil("fmu", "export", "--model", "tcu", "--out", "tcu.fmu", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    done = dsg_hil("run", "-q", "--duration", str(SECONDS), "--controller", "tcu.fmu", "--summary", "s.json",
                   cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert_commands_flowed(json.loads((tmp_path / "s.json").read_text()))


def test_a_sweep_s_module_factory(tmp_path, monkeypatch):
    """The sweep's ``kind = "python"`` controller: ``target = "module:factory"`` imported and built per run (the
    sweep's own run path, :func:`dsg_hil.sweep.controllers.config_for`, without a Dask cluster)."""
    (tmp_path / "my_controller.py").write_text(
        "class Hold:\n"
        "    def step(self, t, inputs):\n"
        f"        return {{'P_CL_Cmd': {Hold.P_CL_MPA}, 'P_CH_Cmd': 0.0}}\n", encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    config = RunConfig(duration=SECONDS, capture=True, **config_for({"kind": "python", "target": "my_controller:Hold"}))
    with open_run(config) as run:
        summary = run.run().as_json()
    assert_commands_flowed(summary)
