"""A dozen short runs through the embedded LocalCluster and through a real cluster (``dask scheduler`` and two
``dask worker`` processes on localhost, the engine's own command line): the same rows from the same seed, also when
one of the workers is killed midway (its runs retried, not lost)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from dsg_hil.results.outcome import RUN_SPECIFIC
from dsg_hil.sweep.results import read_table

from .conftest import REPO, SMALL, sweep, sweep_env

NOT_COMPARED = {*RUN_SPECIFIC, "wall_s"}  # where and how fast a run ran, not what it gave


def comparable(out: Path) -> list[dict]:
    rows = read_table(out).to_pylist()
    return sorted(({k: v for k, v in r.items() if k not in NOT_COMPARED} for r in rows), key=lambda r: r["run_id"])


@pytest.fixture(scope="module")
def embedded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, subprocess.CompletedProcess[str]]:
    where = tmp_path_factory.mktemp("embedded")
    (where / "small.toml").write_text(SMALL, encoding="utf-8")
    with contextlib.ExitStack() as stack:  # Dask's default HTTP port taken, as by another sweep on the machine
        held = stack.enter_context(socket.socket())
        with contextlib.suppress(OSError):  # already taken by somebody else: as good
            held.bind(("", 8787))
            held.listen()
        proc = sweep(str(where / "small.toml"), "--out", str(where / "out"), "--workers", "2")
    return where / "out", proc


@pytest.mark.slow
def test_a_dozen_runs_on_the_embedded_local_cluster(embedded):
    out, proc = embedded
    assert proc.returncode in (0, 3), proc.stderr[-3000:]
    rows = read_table(out).to_pylist()
    assert sorted(r["index"] for r in rows) == list(range(12))
    assert len({r["run_id"] for r in rows}) == 12
    assert all(r["verdict"] in ("ok", "violation", "outside_range") and r["max_plate_temp_c"] > 0 for r in rows), rows
    # SMALL draws plates up to 200 degC, beyond the operating range's 150: those say so unless they violate
    assert all((r["verdict"] == "outside_range") == (r["verdict"] != "violation" and r["outside_range"] != "")
               for r in rows) and any(r["outside_range"] for r in rows)
    assert {r["in.driver.behaviour"] for r in rows} == {"creep", "brake_drag", "stop_and_go", "creep_toggles"}
    violating = [r for r in rows if r["verdict"] == "violation"]
    assert proc.returncode == (3 if violating else 0)  # the exit status says the verdict
    assert f"verdict: {len(violating)} of 12 runs violate" in proc.stderr
    assert "LocalCluster, 2 workers" in proc.stderr and "ETA" in proc.stderr
    assert "already in use" not in proc.stderr  # the cluster took free ports, not Dask's default 8787
    page = (out / "sweep.md").read_text(encoding="utf-8")
    assert "Hottest runs" in page and (out / "margin_histogram.png").exists() and (out / "worst_run.png").exists()
    for row in violating:  # each violation: its reproducing files next to the page
        assert (out / "violations" / row["run_id"] / "scenario.toml").exists()
        assert f"dsg-hil run --scenario violations/{row['run_id']}/scenario.toml" in page
    assert len(list((out / "runs").glob("*.json"))) == 12


def bench(script: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(REPO / "bench" / script), *args], capture_output=True, text=True,
                          timeout=600, env=sweep_env(), cwd=REPO)


@pytest.mark.slow
def test_the_benches_over_a_sweep_read_it_and_repeat_its_runs(embedded):
    """bench/safety_findings.py counts the table; bench/rerun_sweep_runs.py runs two of its runs again on this tree
    (the sweep's own worker) and gets their rows again, key for key; a run that is not there is exit 2, one line."""
    out, _ = embedded
    rows = {r["run_id"]: r for r in read_table(out).to_pylist()}
    found = bench("safety_findings.py", str(out), "--json")
    assert found.returncode == 0, found.stderr
    facts = json.loads(found.stdout)
    hottest = max(r["max_plate_temp_c"] for r in rows.values())
    assert facts["runs"] == 12 and facts["hottest_plate_c"] == round(hottest, 2)
    ids = sorted(rows)[:2]
    keys = "verdict,max_plate_temp_c,handover_deviation_pct,handover_deviation_unbraked_pct,rollback_m,v_max_mps"
    again = bench("rerun_sweep_runs.py", str(out), ids[0], ids[1].split("-")[0], "--keys", keys, "--json")
    assert again.returncode == 0, again.stderr
    pairs = [json.loads(line) for line in again.stdout.splitlines()]
    assert [p["run_id"] for p in pairs] == ids
    for pair in pairs:
        assert pair["now"] == pair["then"] == {k: rows[pair["run_id"]][k] for k in keys.split(",")}
    missing = bench("rerun_sweep_runs.py", str(out), "r99999")
    assert missing.returncode == 2 and missing.stderr.strip() == f"rerun_sweep_runs: {out}/runs: no run r99999"


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _wait_for_workers(address: str, n: int, timeout: float = 180.0) -> None:
    from distributed import Client

    with Client(address, timeout="60s") as client:
        client.wait_for_workers(n, timeout=timeout)


@contextlib.contextmanager
def local_cluster(n_workers: int, nanny: bool = True) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """``dask scheduler`` and ``n_workers`` ``dask worker`` processes on localhost (the engine's own CLI): the
    scheduler's address and the worker processes (without a nanny: the process is the worker)."""
    dask = [str(Path(sys.executable).with_name("dask"))]
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = sweep_env()
    procs = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)]
    try:
        time.sleep(1.0)
        workers = [subprocess.Popen([*dask, "worker", address, "--nthreads", "1", "--nworkers", "1",
                                     "--no-dashboard", "--host", "127.0.0.1", *([] if nanny else ["--no-nanny"])],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
                   for _ in range(n_workers)]
        procs += workers
        _wait_for_workers(address, n_workers)
        yield address, workers
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.mark.slow
def test_the_same_sweep_on_a_real_cluster_gives_the_same_rows(embedded, tmp_path):
    """dask scheduler + two dask worker processes (the engine's own CLI), reached by --scheduler."""
    (tmp_path / "small.toml").write_text(SMALL, encoding="utf-8")
    with local_cluster(2) as (address, _):
        proc = sweep(str(tmp_path / "small.toml"), "--out", str(tmp_path / "out"), "--scheduler", address)
    out, first = embedded
    assert proc.returncode == first.returncode, proc.stderr[-3000:]
    assert f"cluster {address}, 2 workers" in proc.stderr
    assert comparable(tmp_path / "out") == comparable(out)  # same seed, same rows, wherever they ran


def _busy_worker(address: str, workers: list[subprocess.Popen[bytes]], deadline: float) -> subprocess.Popen[bytes]:
    """The worker process that is running one of the sweep's runs (asked of the scheduler)."""
    from distributed import Client

    with Client(address, timeout="60s") as client:
        pids = client.run(os.getpid)  # worker address -> pid
        while time.monotonic() < deadline:
            busy = [pids.get(w) for w, keys in client.processing().items()
                    if any(str(k).startswith("dsg-hil-") for k in keys)]
            for proc in workers:
                if proc.pid in busy:
                    return proc
            time.sleep(0.05)
    raise AssertionError("no worker ever ran one of the sweep's runs")


@pytest.mark.slow
def test_a_lost_workers_runs_are_retried_not_lost(embedded, tmp_path):
    """One of two workers (no nanny to restart it) is killed with SIGKILL while it runs one of the sweep's runs:
    the other worker runs it again; every run is in the table exactly once, with the rows of the embedded sweep."""
    space = tmp_path / "small.toml"
    space.write_text(SMALL, encoding="utf-8")
    out = tmp_path / "out"
    with local_cluster(2, nanny=False) as (address, workers):
        proc = subprocess.Popen([sys.executable, "-m", "dsg_hil", "sweep", str(space), "--out", str(out),
                                 "--scheduler", address], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env=sweep_env(), cwd=REPO)
        try:
            deadline = time.monotonic() + 240.0
            while not list((out / "runs").glob("*.json")) and time.monotonic() < deadline and proc.poll() is None:
                time.sleep(0.05)  # both workers warm and at work
            victim = _busy_worker(address, workers, deadline)
            victim.send_signal(signal.SIGKILL)
            victim.wait()
            done_at_kill = len(list((out / "runs").glob("*.json")))
            _, stderr = proc.communicate(timeout=600)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert done_at_kill < 12, "the worker was to be killed midway"
    _, first = embedded
    assert proc.returncode == first.returncode, stderr[-3000:]
    rows = read_table(out).to_pylist()
    assert sorted(r["run_id"] for r in rows) == sorted({r["run_id"] for r in rows})  # each once
    assert len(rows) == 12 and all(r["verdict"] != "error" for r in rows), rows
    assert comparable(out) == comparable(embedded[0])  # the retried runs gave what they give anywhere
