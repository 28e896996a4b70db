"""The sweep's engine: Dask distributed. With no option a ``LocalCluster`` of worker processes, one thread each, one
per core (the numba cache warmed here first, so no two workers compile it); ``scheduler`` (or
``DASK_SCHEDULER_ADDRESS``) runs the same tasks on an existing cluster. Tasks carry plain data (a run's scenario
text and parameter overrides); results are stored as they complete; a lost worker's runs are run again on another
worker by Dask's scheduler (tested by killing a worker of a real cluster midway).

    from dsg_hil.sweep import load_space, run_sweep

    result = run_sweep(load_space("safety.toml"), "sweep-out", n=40)
    print(len(result.rows), len(result.violations))
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..common.errors import InputError, RunError
from .code import code_digest
from .results import ResultStore, read_manifest, write_manifest
from .space import Space
from .worker import run_task, warm

__all__ = ["RETRIES", "Progress", "SweepResult", "open_client", "resumed_n", "run_sweep", "scheduler_address",
           "start_manifest", "submit"]

RETRIES = 2  # a task that raised (in Dask, e.g. its worker could not import it) is run again this often; a task whose
# worker died is run again by the scheduler (``distributed.scheduler.allowed-failures``, default 3 workers lost)


@dataclass
class SweepResult:
    """What a sweep (or search) gives: every row (run order), the violating ones, how many ran now and how many
    were already there (``--resume``), the wall time, the dashboard link if any."""

    out: Path
    rows: list[dict[str, Any]]
    ran: int
    skipped: int
    wall_s: float
    dashboard: str | None = None
    counterexample: Path | None = None
    search: dict[str, Any] = field(default_factory=dict)

    @property
    def violations(self) -> list[dict[str, Any]]:
        return [r for r in self.rows if r.get("verdict") == "violation"]


class Progress:
    """One progress line at most every ``every`` s: done/total, violations, rate, ETA (and the dashboard)."""

    def __init__(self, total: int, say: Callable[[str], None] | None, dashboard: str | None,
                 every: float = 2.0) -> None:
        self.total, self.say, self.every, self.dashboard = total, say, every, dashboard
        self.done = self.violations = self.errors = 0
        self.t0 = self._last = time.monotonic()

    def update(self, row: dict[str, Any]) -> None:
        self.done += 1
        self.violations += row.get("verdict") == "violation"
        self.errors += row.get("verdict") == "error"
        self.line(final=self.done == self.total)

    def line(self, final: bool = False) -> None:
        now = time.monotonic()
        if self.say is None or (not final and now - self._last < self.every):
            return
        self._last = now
        elapsed = now - self.t0
        rate = self.done / elapsed if elapsed > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else float("nan")
        eta_text = time.strftime("%H:%M:%S", time.gmtime(eta)) if eta == eta else "?"
        self.say(f"sweep: {self.done}/{self.total} runs, {self.violations} violating, {self.errors} failed, "
                 f"{rate * 60:.1f} runs/min, ETA {eta_text}" + (f" | dashboard {self.dashboard}"
                                                                  if self.dashboard else ""))


def scheduler_address(scheduler: str | None) -> str | None:
    """The cluster a sweep runs on: ``--scheduler``, else ``DASK_SCHEDULER_ADDRESS``; None: a local one."""
    return scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None


@contextlib.contextmanager
def open_client(workers: int | None = None, scheduler: str | None = None,
                say: Callable[[str], None] | None = None) -> Iterator[tuple[Any, str | None]]:
    """A Dask client and its dashboard link (None if there is none): on ``scheduler`` (or
    ``DASK_SCHEDULER_ADDRESS``), else on a ``LocalCluster`` of ``workers`` processes (default: one per core)."""
    try:
        from distributed import Client, LocalCluster  # noqa: PLC0415
    except ImportError as exc:
        raise InputError("dsg-hil sweep needs Dask distributed: pip install 'dsg-hil[sweep]'") from exc
    address = scheduler_address(scheduler)
    if address is not None and workers is not None:
        raise InputError("--workers: the cluster at --scheduler (or DASK_SCHEDULER_ADDRESS) has its own workers")
    with contextlib.ExitStack() as stack:
        if address is None:
            warm()  # the numba cache compiled once, here, before any worker starts
            # a free port: the scheduler's HTTP server starts with or without bokeh (the dashboard needs it), and on
            # its default 8787 a second sweep on the machine prints 'Port 8787 is already in use' first
            dashboard = ":0"
            with _workers_ignore_ctrl_c():
                cluster = stack.enter_context(LocalCluster(
                    n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                    silence_logs=logging.CRITICAL, dashboard_address=dashboard))  # shutdown's heartbeat noise too
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(address, timeout="20s"))
            except (OSError, TimeoutError) as exc:
                raise RunError(f"--scheduler {address}: cannot connect ({exc})") from exc
        info = client.scheduler_info()
        link = client.dashboard_link if "dashboard" in info.get("services", {}) else None
        if say is not None:
            n = len(info.get("workers", {}))
            say(f"sweep: Dask {'cluster ' + address if address else 'LocalCluster'}, {n} workers"
                + (f", dashboard {link}" if link else ""))
        yield client, link


@contextlib.contextmanager
def _workers_ignore_ctrl_c() -> Iterator[None]:
    """SIGINT ignored while the local cluster spawns its worker processes: a Python started with SIGINT ignored
    keeps it so (no KeyboardInterrupt, and asyncio's runner installs no handler), so Ctrl-C, which the terminal
    sends to the whole process group, interrupts the sweep here, which closes the cluster, and not every worker
    with a traceback of its own (32 lines each before)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def submit(client: Any, tasks: list[dict[str, Any]], keep_logs: bool) -> list[Any]:
    """The tasks as Dask futures (plain data in, plain data out; run again when their worker is lost)."""
    return [client.submit(run_task, task, keep_logs, key=f"dsg-hil-{task['run_id']}-{time.monotonic_ns()}",
                          retries=RETRIES, pure=False) for task in tasks]


def result_of(future: Any, task: dict[str, Any]) -> dict[str, Any]:
    """A future's result; a task that failed in Dask (its workers lost too often) as a failed run's row."""
    try:
        return dict(future.result())
    except Exception as exc:  # noqa: BLE001 - recorded as the run's error, the sweep goes on
        row = {"run_id": task["run_id"], "index": task["index"], "verdict": "error", "violations": "",
               "error": f"{type(exc).__name__}: {exc}"}
        return {"run_id": task["run_id"], "row": row, "summary": None, "log": None, "traceback": None, "task": task}


def resumed_n(space: Space, out: str | Path, n: int | None, *, search: bool = False) -> int:
    """How many runs a ``--resume`` of the sweep in ``out`` makes: ``n``, or without it the n the sweep was started
    with. The runs there must be ``space``'s, and of the same kind (sampled, or ``search``: a search's trials are
    not a sampler's runs, nor the other way round). Another ``n`` only extends a sampler whose first runs stay the
    same (Sobol): a Latin hypercube of another n draws other runs, and fewer runs than are there is no resume; a
    search's budget may be any n from the trials it has stored on."""
    manifest = read_manifest(out)
    stored = [p.name for p in (Path(out) / "runs").glob("*.json")]
    searched = bool(manifest.get("search")) if manifest is not None else any(s.startswith("s") for s in stored)
    if (manifest is not None or stored) and searched != search:
        raise InputError(f"--resume: {out} holds a search: resume it with --search, or give another --out" if searched
                         else f"--resume --search: {out} holds a sampled sweep, not a search: give another --out")
    if manifest is not None and manifest.get("digest") != space.digest:
        raise InputError(f"--resume: {out} holds a sweep of another space than {space.origin} (sampler, seed, base "
                         f"scenario, inputs, controller or limits differ): give another --out")
    if manifest is None and not search:  # a sweep before OUT/sweep.json: its runs are matched by their IDs
        return space.n if n is None else n
    before = space.n if manifest is None else int(manifest["n"])
    if search:
        n = before if n is None else n
        if n < len(stored):
            raise InputError(f"--n {n}: {out} holds a search of {len(stored)} trials: --resume finishes or extends "
                             f"it (--n {len(stored)} or more)")
        return n
    if n is None or n == before:
        return before
    if not space.stable_prefix:
        raise InputError(f"--n {n}: {out} holds a Latin hypercube sweep of --n {before}, and a Latin hypercube of "
                         f"another n draws other runs: --resume needs --n {before} (a space with sampler = "
                         f"\"sobol\" can be extended)")
    if n < before:
        raise InputError(f"--n {n}: {out} holds a sweep of --n {before}: --resume finishes or extends it "
                         f"(--n {before} or more)")
    return n


def start_manifest(space: Space, out: str | Path, n: int, *, resume: bool, search: bool = False,
                   progress: Callable[[str], None] | None = None) -> None:
    """``OUT/sweep.json`` written for the sweep (or ``search``) of ``n`` runs starting now; on ``resume``, a warning
    first if the runs there were made by other code than this install (the table will mix the two)."""
    before = read_manifest(out) if resume else None
    if progress is not None and before is not None and before.get("code", code_digest()) != code_digest():
        progress(f"sweep: warning: {out}'s runs were made by other code ({before['code']}) than this install "
                 f"({code_digest()}); the table will mix the two (column 'code')")
    write_manifest(out, {"space": space.name, "origin": space.origin, "digest": space.digest,
                         "sampler": "tpe" if search else space.sampler, "n": n, "code": code_digest(),
                         **({"search": True} if search else {})})


def run_sweep(space: Space, out: str | Path, *, n: int | None = None, workers: int | None = None,
              scheduler: str | None = None, resume: bool = False, keep_logs: bool = False,
              progress: Callable[[str], None] | None = None) -> SweepResult:
    """Run ``n`` (default: the space's) samples of ``space``, results into ``out`` as they finish (see
    :mod:`dsg_hil.sweep.results`); ``resume``: skip the runs already there (``n`` default: the sweep's own;
    another n as :func:`resumed_n` allows)."""
    t0 = time.monotonic()
    n = resumed_n(space, out, n) if resume else (space.n if n is None else n)
    tasks = space.tasks(n)
    store = ResultStore(out, resume=resume)
    start_manifest(space, out, n, resume=resume, progress=progress)
    todo = [t for t in tasks if t["run_id"] not in store.done]
    skipped = len(tasks) - len(todo)
    if progress is not None and skipped:
        progress(f"sweep: {skipped} of {len(tasks)} runs already in {out} (--resume): skipped")
    link = None
    try:
        if todo:
            with open_client(workers, scheduler, progress) as (client, link):
                bar = Progress(len(todo), progress, link)
                futures = submit(client, todo, keep_logs)
                by_key = {f.key: t for f, t in zip(futures, todo)}
                from distributed import as_completed  # noqa: PLC0415

                for future in as_completed(futures):
                    result = result_of(future, by_key[future.key])
                    store.add(result)
                    bar.update(result["row"])
    finally:
        store.flush()
    wanted = {t["run_id"] for t in tasks}
    rows = [r for r in store.rows() if r["run_id"] in wanted]
    return SweepResult(Path(out), rows, len(todo), skipped, time.monotonic() - t0, link)
