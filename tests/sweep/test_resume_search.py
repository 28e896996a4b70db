"""Results are never lost: a sweep killed midway resumes with nothing repeated and nothing lost; --resume with a
larger --n extends a Sobol sweep by the missing runs and refuses what would mix sweeps. The search finds a
planted violation (a controller that holds CL slipping against the brake) within its budget and writes it as a
runnable scenario."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dsg_hil.sim.scenario import load_scenario
from dsg_hil.sweep.code import code_digest
from dsg_hil.sweep.results import read_table
from dsg_hil.sweep.space import load_space, parse_space
from dsg_hil.testing import run_plant

from .conftest import REPO, SMALL, sweep, sweep_env
from .unsafe import Slipper


def kill_after_three_runs(argv: list[str], out: Path, poll_s: float = 0.1) -> None:
    """Start the sweep ``argv`` and SIGKILL it with its cluster (its process group, at once: no clean-up) once
    ``out/runs`` holds three runs (or after 240 s, or when it ended)."""
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=sweep_env(), cwd=REPO,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 240.0
        while len(list((out / "runs").glob("*.json"))) < 3 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(poll_s)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


@pytest.mark.slow
def test_a_sweep_killed_midway_resumes_with_nothing_repeated_and_nothing_lost(tmp_path):
    space = tmp_path / "small.toml"
    space.write_text(SMALL, encoding="utf-8")
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "dsg_hil", "sweep", str(space), "--out", str(out), "--workers", "1"]
    kill_after_three_runs(argv, out)
    before = {p.name: p.stat().st_mtime_ns for p in (out / "runs").glob("*.json")}
    assert 3 <= len(before) < 12, "the sweep was to be killed midway"
    again = sweep(str(space), "--out", str(out), "--workers", "1", "--resume")
    assert again.returncode in (0, 3), again.stderr[-3000:]
    assert f"{len(before)} of 12 runs already in {out} (--resume): skipped" in again.stderr
    assert f"sweep: 12/{12 - len(before)} runs" not in again.stderr
    after = {p.name: p.stat().st_mtime_ns for p in (out / "runs").glob("*.json")}
    assert len(after) == 12 and all(after[name] == mtime for name, mtime in before.items())  # none run again
    ids = read_table(out).column("run_id").to_pylist()
    assert sorted(ids) == sorted(name.removesuffix(".json") for name in after)  # each once, none lost


@pytest.mark.slow
def test_ctrl_c_ends_a_sweep_with_one_line_and_no_worker_tracebacks(tmp_path):
    """Ctrl-C (SIGINT to the sweep's whole process group, as a terminal sends it) once the cluster is up: exit 130,
    'error: interrupted', and no traceback from the workers (each printed 32 lines of one before)."""
    space = tmp_path / "small.toml"
    space.write_text(SMALL, encoding="utf-8")
    argv = [sys.executable, "-m", "dsg_hil", "sweep", str(space), "--out", str(tmp_path / "out"), "--workers", "2"]
    # SIGINT at its default in the sweep, as in a terminal: a test run started in the background of a shell without
    # job control (nohup, '&' in a script) hands its children SIGINT ignored, and a Python started so keeps it
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=sweep_env(),
                            cwd=REPO, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # noqa: PLW1509
    try:
        first = proc.stderr.readline()  # the cluster's line, once its workers have started
        assert first.startswith("sweep: Dask LocalCluster, 2 workers"), first
        os.killpg(proc.pid, signal.SIGINT)
        rest = proc.communicate(timeout=120)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, rest[-3000:]
    assert "Traceback" not in rest and "KeyboardInterrupt" not in rest, rest[-3000:]
    assert rest.strip().splitlines()[-1] == "error: interrupted"


def _error_line(proc: subprocess.CompletedProcess[str]) -> str:
    assert proc.returncode == 2, proc.stderr[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    return lines[0]


@pytest.mark.slow
def test_resume_with_a_larger_n_extends_a_sobol_sweep_with_only_the_missing_runs(tmp_path):
    space = tmp_path / "sobol.toml"
    space.write_text(SMALL.replace("seed = 7", 'seed = 7\nsampler = "sobol"'), encoding="utf-8")
    out = tmp_path / "out"
    first = sweep(str(space), "--out", str(out), "--workers", "1", "--n", "3")
    assert first.returncode in (0, 3), first.stderr[-3000:]
    before = {p.name: p.stat().st_mtime_ns for p in (out / "runs").glob("*.json")}
    assert len(before) == 3
    manifest = json.loads((out / "sweep.json").read_text(encoding="utf-8"))
    assert manifest["code"] == code_digest() and set(read_table(out).column("code").to_pylist()) == {code_digest()}
    assert "other code" not in first.stderr
    # as if the code had changed since: the resume says the table will mix the two
    (out / "sweep.json").write_text(json.dumps({**manifest, "code": "0123456789ab"}), encoding="utf-8")
    fewer = _error_line(sweep(str(space), "--out", str(out), "--resume", "--n", "2"))
    assert "--n 2" in fewer and "--n 3 or more" in fewer
    more = sweep(str(space), "--out", str(out), "--workers", "1", "--resume", "--n", "5")
    assert more.returncode in (0, 3), more.stderr[-3000:]
    assert f"3 of 5 runs already in {out} (--resume): skipped" in more.stderr and "sweep: 2/2 runs" in more.stderr
    assert f"runs were made by other code (0123456789ab) than this install ({code_digest()})" in more.stderr
    after = {p.name: p.stat().st_mtime_ns for p in (out / "runs").glob("*.json")}
    assert all(after[name] == mtime for name, mtime in before.items())  # none run again
    ids = read_table(out).column("run_id").to_pylist()
    assert sorted(ids) == sorted(t["run_id"] for t in load_space(space).tasks(5))  # the sweep of 5, each once
    again = sweep(str(space), "--out", str(out), "--resume")  # no --n: the sweep's own (now 5)
    assert again.returncode in (0, 3) and f"5 of 5 runs already in {out}" in again.stderr, again.stderr[-3000:]
    assert len(read_table(out)) == 5


@pytest.mark.slow
def test_resume_refuses_another_n_of_a_latin_hypercube_and_another_space_and_writes_nothing(tmp_path):
    space = tmp_path / "small.toml"
    space.write_text(SMALL, encoding="utf-8")
    out = tmp_path / "out"
    first = sweep(str(space), "--out", str(out), "--workers", "1", "--n", "2")
    assert first.returncode in (0, 3), first.stderr[-3000:]
    state = sorted((p.name, p.stat().st_mtime_ns) for p in out.rglob("*"))
    other_n = _error_line(sweep(str(space), "--out", str(out), "--resume", "--n", "4"))
    assert "--n 4" in other_n and "Latin hypercube sweep of --n 2" in other_n and "--resume needs --n 2" in other_n
    space.write_text(SMALL.replace("seed = 7", "seed = 8"), encoding="utf-8")
    other_space = _error_line(sweep(str(space), "--out", str(out), "--resume"))
    assert f"{out} holds a sweep of another space than {space}" in other_space
    searched = _error_line(sweep(str(space), "--out", str(out), "--search", "--resume"))
    assert f"--resume --search: {out} holds a sampled sweep, not a search: give another --out" in searched
    assert sorted((p.name, p.stat().st_mtime_ns) for p in out.rglob("*")) == state


SEARCH = """
name = "planted"
seed = 3
n = 40
duration_s = 4.0
[inputs]
"initial.T_clutch_c" = {uniform = [100, 210]}  # above ~200 degC: CL passes 250 degC in 4 s
grade_rad = {uniform = [0.0, 0.2]}
"params.vehicle.m" = {uniform = [6000, 9000]}
"driver.brake_s" = 100.0         # the brake held all the run: the clutch CL slips at the engine's speed
[controller]
kind = "python"
target = "tests.sweep.unsafe:Slipper"
"""


@pytest.mark.slow
def test_the_search_finds_a_planted_violation_within_its_budget(tmp_path):
    space = tmp_path / "planted.toml"
    space.write_text(SEARCH, encoding="utf-8")
    out = tmp_path / "out"
    proc = sweep(str(space), "--out", str(out), "--workers", "2", "--search", "--n", "20")
    assert proc.returncode == 3, proc.stderr[-3000:]
    rows = read_table(out).to_pylist()
    violating = [r for r in rows if r["verdict"] == "violation"]
    assert len(violating) == 1 and len(rows) < 20  # stopped at the first violation
    assert violating[0]["violations"] == "plate" and violating[0]["max_plate_temp_c"] > 250.0
    assert "search: counterexample" in proc.stderr
    logs = sorted(p.name for p in (out / "runs").glob("*.log.gz"))
    assert logs == [f"{violating[0]['run_id']}.log.gz"]  # the violating run's log is kept, no other
    counterexample = out / "counterexample" / "scenario.toml"
    command = (out / "counterexample" / "command.sh").read_text(encoding="utf-8")
    assert command.startswith("dsg-hil run --scenario counterexample/scenario.toml --params counterexample/params.toml")
    rerun = run_plant(Slipper(), scenario=load_scenario(counterexample), params=out / "counterexample" / "params.toml",
                      log=None)  # runnable, and it violates again
    assert max(rerun.summary["max_plate_temp_c"].values()) == violating[0]["max_plate_temp_c"]
    assert "## Search" in (out / "sweep.md").read_text(encoding="utf-8")


def test_the_planted_violation_is_not_everywhere(tmp_path):
    """The search had something to find: most of the space is safe for the same controller."""
    rerun = run_plant(Slipper(), scenario=_scenario(tmp_path, 150.0), log=None)
    assert max(rerun.summary["max_plate_temp_c"].values()) < 230.0  # mid-range: far from 250 degC


def _scenario(tmp_path: Path, T_clutch_c: float) -> Path:
    path = tmp_path / "cool.toml"
    path.write_text(f"duration_s = 4.0\n[initial]\nT_clutch_c = {T_clutch_c}\nT_oil_c = 100.0\n[[driver]]\nt_s = 0.0\n"
                    "creep_request = false\nbrake = 1.0\n", encoding="utf-8")
    return path


def test_the_table_reads_as_one_dataset_when_a_batch_has_a_column_without_values(tmp_path):
    """A first batch of runs that all lack a value (no stop, no error) and a later one that has it: pyarrow and
    pandas read OUT/table as one table (a 200-run sweep's could not: 'Unsupported cast from double to null')."""
    import pyarrow.parquet as pq

    from dsg_hil.sweep.results import ResultStore, read_table

    store = ResultStore(tmp_path / "out", batch_s=0.0)
    for i, (stop, error) in enumerate([(None, None), (None, None), (12.5, None), (None, "RunError: boom")]):
        store.add({"run_id": f"r{i}", "row": {"run_id": f"r{i}", "brake_at_stop": stop, "error": error},
                   "summary": None, "log": None, "traceback": None, "task": {}})
        store.flush()
    table = pq.read_table(tmp_path / "out" / "table")
    assert table.num_rows == 4 and table.column("brake_at_stop").to_pylist() == [None, None, 12.5, None]
    assert table.column("error").to_pylist()[3] == "RunError: boom"
    assert read_table(tmp_path / "out").num_rows == 4


def test_every_part_has_one_schema_whether_a_run_s_first_ch_slip_is_null_or_not(tmp_path):
    """Issue 35, item 9: a run with no first CH slip (mu_CH_first_slip null) wrote one column where the others wrote
    .start/.end; pyarrow.parquet.read_table(OUT/table) took the first part's schema and dropped columns, and
    pyarrow.concat_tables of the parts failed. Now: null runs first, then one with the values, then a failed one."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from dsg_hil.sweep.results import ResultStore
    from dsg_hil.sweep.verdict import summary_row

    store = ResultStore(tmp_path / "out", batch_s=0.0)
    slipped = {"mu_CH_first_slip": {"start": 0.11, "end": 0.12}, "P_CH_first_slip_mpa": {"start": 0.3, "end": 0.4},
               "stop_reason": "STOPPED_OVERHEAT"}
    never = {"mu_CH_first_slip": None, "P_CH_first_slip_mpa": None, "stop_reason": "COMPLETED"}
    rows = [{"verdict": "ok", "error": None, **summary_row(s)} for s in (never, slipped)]
    rows.append({"verdict": "error", "error": "RunError: boom"})  # a failed run: no summary at all
    for i, row in enumerate(rows):
        store.add({"run_id": f"r{i}", "row": {"run_id": f"r{i}", **row}, "summary": None, "log": None,
                   "traceback": None, "task": {}})
        store.flush()
    parts = [pq.read_table(p) for p in sorted((tmp_path / "out" / "table").glob("part-*.parquet"))]
    assert len(parts) == 3 and all(part.schema == parts[0].schema for part in parts), [p.schema for p in parts]
    table = pq.read_table(tmp_path / "out" / "table")
    assert table.column("mu_CH_first_slip.start").to_pylist() == [None, 0.11, None]
    assert table.column("P_CH_first_slip_mpa.end").to_pylist() == [None, 0.4, None]
    assert table.column("error").to_pylist() == [None, None, "RunError: boom"]
    assert pa.concat_tables(parts).num_rows == 3


@pytest.mark.slow
def test_a_sweep_whose_runs_all_fail_is_not_a_pass(tmp_path):
    """Runs that fail (here the controller under test raises) are not judged: no violation, but no pass either.
    Exit 1, the verdict line counts them and names the first error; each row keeps its error."""
    space = tmp_path / "broken.toml"
    space.write_text(SEARCH.replace('name = "planted"', 'name = "broken"').replace("n = 40", "n = 3")
                     .replace("unsafe:Slipper", "unsafe:Crasher"), encoding="utf-8")
    out = tmp_path / "out"
    proc = sweep(str(space), "--out", str(out), "--workers", "1")
    assert proc.returncode == 1, proc.stderr[-3000:]
    rows = read_table(out).to_pylist()
    assert len(rows) == 3 and all(r["verdict"] == "error" for r in rows), rows
    assert all("the controller under test crashed" in r["error"] for r in rows), rows
    verdict = [line for line in proc.stderr.splitlines() if line.startswith("verdict:")]
    assert len(verdict) == 1 and "0 of 3 runs violate; 3 failed, not judged" in verdict[0], proc.stderr[-3000:]


LATENT = "\n[latent]\nper_run = [0, 2]\nscale = [0.1, 2.5]\n"  # drawn by trial index, not proposed


@pytest.mark.slow
def test_a_search_killed_midway_resumes_with_nothing_repeated_and_nothing_lost(tmp_path):
    """A search SIGKILLed after >= 3 stored trials and resumed: the stored trials count against the budget, their
    files stay as they were, the new ones continue the run indices (s00000..s00015, each once, the latent faults
    of each index as an uninterrupted search draws them), and the table has exactly the budget's rows."""
    space = tmp_path / "small.toml"
    space.write_text(SMALL + LATENT, encoding="utf-8")
    out, budget = tmp_path / "out", 16
    argv = [sys.executable, "-m", "dsg_hil", "sweep", str(space), "--out", str(out), "--workers", "1", "--search",
            "--n", str(budget)]
    kill_after_three_runs(argv, out, poll_s=0.02)
    before = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in (out / "runs").glob("*.json")}
    assert 3 <= len(before) < budget, "the search was to be killed midway"
    again = sweep(str(space), "--out", str(out), "--workers", "1", "--search", "--resume", "--n", str(budget))
    assert again.returncode == 0, again.stderr[-3000:]
    after = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in (out / "runs").glob("*.json")}
    assert all(after[name] == stored for name, stored in before.items())  # none run again nor rewritten
    assert [name.split("-")[0] for name in sorted(after)] == [f"s{i:05d}" for i in range(budget)]
    ids = read_table(out).column("run_id").to_pylist()
    assert sorted(ids) == sorted(name.removesuffix(".json") for name in after)  # each once, none lost
    assert f"search: {len(before)} of {budget} trials already in {out} (--resume)" in again.stderr
    left = budget - len(before)
    assert f"sweep: {left}/{left} runs" in again.stderr, again.stderr[-3000:]
    loaded = load_space(space)
    for name in after:
        task = json.loads(after[name][1])["task"]
        assert task["inputs"]["latent"] == loaded.with_latent(task["index"], task["inputs"])["latent"], name
    # done: without --n, the search's own budget, and nothing left to run; a sampled --resume, or a search of
    # another space, is refused, nothing written
    done = sweep(str(space), "--out", str(out), "--search", "--resume")
    assert done.returncode == 0 and f"{budget} of {budget} trials already in {out}" in done.stderr, done.stderr
    assert "Dask" not in done.stderr and len(read_table(out)) == budget
    state = sorted((p.name, p.stat().st_mtime_ns) for p in out.rglob("*"))
    sampled = _error_line(sweep(str(space), "--out", str(out), "--resume"))
    assert f"{out} holds a search: resume it with --search" in sampled
    space.write_text((SMALL + LATENT).replace("seed = 7", "seed = 8"), encoding="utf-8")
    other = _error_line(sweep(str(space), "--out", str(out), "--search", "--resume"))
    assert f"{out} holds a sweep of another space than {space}" in other
    assert sorted((p.name, p.stat().st_mtime_ns) for p in out.rglob("*")) == state


def _stored_search(tmp_path: Path, values: list[float | None], violation: int | None = None,
                   lost: tuple[int, ...] = ()):
    """A search's folder as a search leaves it: one trial per value (None: a failed run), proposed by a study of
    its own, its record in OUT/runs (but those of the indices ``lost``: in flight when it was killed); and that
    study's trials."""
    import optuna

    from dsg_hil.sweep.results import ResultStore
    from dsg_hil.sweep.search import suggest

    space = parse_space(SMALL + LATENT, str(tmp_path / "small.toml"))
    store = ResultStore(tmp_path / "out")
    study = optuna.create_study(direction="maximize", sampler=optuna.samplers.TPESampler(seed=1))
    for index, value in enumerate(values):
        trial = study.ask()
        task = space.task(index, space.with_latent(index, {k: suggest(trial, k, d) for k, d in space.inputs.items()}))
        task["run_id"] = "s" + task["run_id"][1:]
        row = {"run_id": task["run_id"], "index": index, **{f"in.{k}": str(v) for k, v in task["inputs"].items()},
               "verdict": "error" if value is None else "violation" if index == violation else "ok",
               "violations": "plate" if index == violation else "", "max_plate_temp_c": value}
        if index not in lost:
            store.add({"run_id": task["run_id"], "row": row, "summary": None, "log": None, "traceback": None,
                       "task": task})
        study.tell(trial, value, state=None if value is not None else optuna.trial.TrialState.FAIL)
    store.flush()
    return space, tmp_path / "out", study.trials


def test_a_resumed_search_s_study_holds_the_stored_trials_before_it_proposes_new_ones(tmp_path):
    """The stored trials, told to the new study: their values (a failed run as failed), the parameters the search
    proposed (a choice as its index; the latent faults, drawn by index, none of them); the next trial is the sixth."""
    import optuna

    from dsg_hil.sweep.results import ResultStore
    from dsg_hil.sweep.search import search_study, stored_trials

    space, out, proposed = _stored_search(tmp_path, [120.0, 150.5, None, 131.0, 99.0])
    stored = stored_trials(space, ResultStore(out, resume=True))
    assert [index for index, _, _ in stored] == [0, 1, 2, 3, 4]
    study = search_study(space, 16, [trial for _, trial, _ in stored])
    assert [t.value for t in study.trials] == [120.0, 150.5, None, 131.0, 99.0]
    assert [t.state for t in study.trials].count(optuna.trial.TrialState.FAIL) == 1
    assert [t.params for t in study.trials] == [t.params for t in proposed]
    assert [t.distributions for t in study.trials] == [t.distributions for t in proposed]
    assert all("latent" not in t.params and t.params["driver.behaviour"] in range(4) for t in study.trials)
    assert study.best_value == 150.5
    assert study.ask().number == 5


def test_a_resumed_search_whose_stored_trial_violates_reports_it_and_runs_nothing(tmp_path):
    """No cluster is started (nothing is left to run): the stored violation is the counterexample."""
    from dsg_hil.sweep.search import run_search

    space, out, _ = _stored_search(tmp_path, [120.0, 260.0, 131.0], violation=1)
    result = run_search(space, out, budget=16, resume=True, workers=1)
    assert result.ran == 0 and result.skipped == 3 and len(result.rows) == 3
    assert result.search["counterexample"] == result.rows[1]["run_id"] and result.search["best"] == 260.0
    assert result.search["runs"] == 3 and result.counterexample == out / "counterexample"
    assert (out / "counterexample" / "scenario.toml").exists()
    assert sorted(p.name for p in (out / "runs").glob("*.json")) == sorted(r["run_id"] + ".json" for r in result.rows)


def test_a_search_does_not_resume_onto_a_sampled_sweep_or_past_its_budget(tmp_path):
    from dsg_hil.common.errors import InputError
    from dsg_hil.sweep.search import run_search

    space, out, _ = _stored_search(tmp_path, [120.0, 150.5, 131.0])
    with pytest.raises(InputError, match=f"--n 2: {out} holds a search of 3 trials: --resume finishes or extends it"):
        run_search(space, out, budget=2, resume=True)
    for path in (out / "runs").glob("*.json"):
        path.rename(path.with_name("r" + path.name[1:]))  # as if a sampled sweep's, from before OUT/sweep.json
    with pytest.raises(InputError, match=f"--resume --search: {out} holds a sampled sweep, not a search"):
        run_search(space, out, budget=16, resume=True)


@pytest.mark.slow
def test_a_resumed_search_runs_first_the_indices_that_were_in_flight_when_it_was_killed(tmp_path):
    """Killed with several runs in flight, a search leaves gaps in its indices: the resumed one runs those first,
    then the next, so that its indices end as an uninterrupted search's (s00000..s00004), each run once."""
    from dsg_hil.sweep.search import run_search

    space, out, _ = _stored_search(tmp_path, [120.0, 150.5, 131.0, 99.0], lost=(2,))
    before = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in (out / "runs").glob("*.json")}
    result = run_search(space, out, budget=5, resume=True, workers=1)
    assert result.ran == 2 and result.skipped == 3 and result.search["runs"] == 5
    after = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in (out / "runs").glob("*.json")}
    assert all(after[name] == stored for name, stored in before.items())
    assert [name.split("-")[0] for name in sorted(after)] == [f"s{i:05d}" for i in range(5)]
