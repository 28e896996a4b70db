"""open_run, the one way to assemble a run: every entry point gives the same summary for the same scenario, the
summary is typed and round-trips through JSON, it is written however the run ends, and bad input fails before
anything runs or is written."""

from __future__ import annotations

import gc
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from dsg_hil.common.errors import InputError
from dsg_hil.protocol.faults import FaultError
from dsg_hil.results.outcome import RUN_SPECIFIC, Summary
from dsg_hil.results.summary import CreepMetrics
from dsg_hil.sim.loop import run_closed_loop
from dsg_hil.sim.run import ECU_STUB, RunConfig, open_run, setup_frozen
from dsg_hil.sim.scenario import load_scenario
from dsg_hil.testing import run_plant

DURATION = 3.0


def comparable(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in RUN_SPECIFIC}


@pytest.mark.slow
def test_the_entry_points_give_the_same_summary_key_for_key(tmp_path):
    cli_path = tmp_path / "cli.json"
    subprocess.run([sys.executable, "-m", "dsg_hil", "run", "-i", "virtual", "--duration", str(DURATION),
                    "--summary", str(cli_path)], check=True, capture_output=True, timeout=600)
    cli = json.loads(cli_path.read_text())
    with open_run(RunConfig(duration=DURATION)) as run:
        api = run.run().as_json()
    loop = run_closed_loop(load_scenario().with_duration(DURATION)).summary
    plugin = run_plant(duration=DURATION, log=None).summary
    assert list(cli) == list(api) == list(loop) == list(plugin)  # the same keys, in the same order
    for other in (api, loop, plugin):
        assert comparable(other) == comparable(cli)
    assert cli["sim_time_s"] == DURATION and cli["frames"]["sent"] > 0
    assert cli["interface"].startswith("virtual:") and api["interface"].startswith("local:")


def test_the_summary_is_typed_and_round_trips_through_json(tmp_path):
    path = tmp_path / "s.json"
    with open_run(RunConfig(duration=1.0, summary=path)) as run:
        summary = run.run()
    assert isinstance(summary, Summary) and summary.sim_time_s == 1.0 and summary.mode == "lockstep"
    assert summary.stop_reason == summary["stop_reason"] == "end_of_record"
    data = json.loads(path.read_text())
    assert data == summary.as_json()
    assert Summary.from_json(data) == summary
    with pytest.raises(InputError, match="not a dsg-hil summary"):
        Summary.from_json({"scenario": "x"})


def test_the_summary_names_every_creep_metric():
    from dsg_hil.results.outcome import _METRIC_KEYS

    assert set(CreepMetrics().as_json()) == _METRIC_KEYS


def test_truth_and_frames_are_kept_when_asked(tmp_path):
    with open_run(RunConfig(duration=0.5, capture=True, truth=True, log=tmp_path / "run.log")) as run:
        run.run()
    truth = run.truth()
    assert len(truth["t"]) == 50 and truth["t"][1] == pytest.approx(0.01)
    assert truth["T_CL"][0] == pytest.approx(run.scenario.T_CL_c, abs=1.0)
    assert len(run.frames) == len((tmp_path / "run.log").read_text().splitlines())


def test_a_run_ended_early_still_writes_the_summary_with_its_stop_reason(tmp_path):
    class Interrupted:
        """ecu-stub, until Ctrl-C comes at 0.2 s of simulated time."""

        def __init__(self, db, bus):
            from dsg_hil.protocol import Codec
            from ecu_stub.runner import TCU_USES, TcuRunner

            self.inner, self.bus = TcuRunner(Codec(db, TCU_USES), bus), bus

        @property
        def now(self):
            return self.inner.now

        def pump(self):
            if self.inner.now >= 0.2:
                raise KeyboardInterrupt
            self.inner.pump()

    path = tmp_path / "s.json"
    config = RunConfig(duration=2.0, tcu=lambda db, bus: Interrupted(db, bus), summary=path)
    with pytest.raises(KeyboardInterrupt), open_run(config) as run:
        run.run()
    data = json.loads(path.read_text())
    assert data["stop_reason"] == "interrupted" and 0.2 <= data["sim_time_s"] < 2.0


@pytest.mark.parametrize(("config", "error", "needle"), [
    (RunConfig(tcu="nosuch"), InputError, "RunConfig.tcu 'nosuch'"),
    (RunConfig(mode="fast"), InputError, "RunConfig.mode 'fast'"),  # type: ignore[arg-type]
    (RunConfig(tcu=None), InputError, "needs a bus"),
    (RunConfig(bus={"interface": "virtual", "channel": "x"}, tcu=None, faults=["drop:TCU_CMD@1-2"]), FaultError,
     "changes the TCU's frames"),
    (RunConfig(params={"vehicle.nosuch": 1.0}), InputError, "no parameter 'vehicle.nosuch'"),
    (RunConfig(scenario="/nonexistent/creep.toml"), InputError, "cannot read scenario"),
    (RunConfig(faults=["explode:TCU_CMD"]), InputError, "kind must be one of"),
])
def test_bad_input_fails_before_anything_runs_or_is_written(tmp_path, config, error, needle):
    from dataclasses import replace

    config = replace(config, log=tmp_path / "run.log", summary=tmp_path / "s.json")
    with pytest.raises(error, match=needle):
        open_run(config)
    assert list(tmp_path.iterdir()) == []


def test_default_tcu_is_the_bundled_ecu_stub():
    assert RunConfig().tcu == ECU_STUB


@pytest.mark.slow
def test_the_tutorial_example_runs(tmp_path):
    page = Path(__file__).resolve().parents[2] / "docs" / "tutorials" / "python.md"
    block = re.search(r"```python\n(.*?)```", page.read_text(encoding="utf-8"), re.S)
    assert block, "docs/tutorials/python.md: no python block"
    proc = subprocess.run([sys.executable, "-c", block.group(1)], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((tmp_path / "summary.json").read_text())["faults"]["injected"]
    assert (tmp_path / "run.asc").stat().st_size > 0


@pytest.mark.slow
def test_the_set_up_is_frozen_for_the_run_and_thawed_after():
    """setup_frozen: the objects made before the run out of the collector's way during it (gc.freeze), back after
    (a sweep worker's next run collects this one's cycles); someone else's freeze left as it was."""
    assert gc.get_freeze_count() == 0
    seen = []
    with open_run(RunConfig(scenario=load_scenario().with_duration(0.5),
                            on_period=lambda runner: seen.append(gc.get_freeze_count()))) as run:
        run.run()
    assert seen and min(seen) > 1000 and gc.get_freeze_count() == 0
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        with setup_frozen():
            assert gc.get_freeze_count() == frozen
        assert gc.get_freeze_count() == frozen
    finally:
        gc.unfreeze()
