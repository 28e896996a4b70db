"""One run of a sweep, in a worker: a task (plain data, :meth:`dsg_hil.sweep.space.Space.task`) in, a result (plain
data: the table row, the summary JSON, the log if kept) out. The plant is imported and warmed once per process;
the numba cache is compiled by one process at a time (a Dask lock when in a Dask worker)."""

from __future__ import annotations

import contextlib
import functools
import gzip
import logging
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any
from collections.abc import Iterator

from cantools.database import Database

from ..physics.params import load_params, with_overrides
from ..protocol.codec import load_dbc
from ..protocol.faults import parse_fault
from ..sim.run import RunConfig, open_run
from ..results.thresholds import STOP_MIN_S
from ..sim.scenario import Scenario, parse_scenario
from .code import code_digest
from .controllers import config_for
from .latent import largest_multiple
from .verdict import UnexplainedFault, fault_windows, in_windows, summary_row, verdict, violations

__all__ = ["RUN_LOGGERS", "WARM_LOCK", "pedal_while_stopping", "run_task", "runs_quiet", "warm"]

WARM_LOCK = "dsg-hil-numba-warm"
_warmed = False


def warm() -> None:
    """Compile (or load from the cache) the plant's compiled code in this process: a 0.05-s run."""
    global _warmed  # noqa: PLW0603 - once per process
    if not _warmed:
        with open_run(RunConfig(duration=0.05)) as run:
            run.run()
        _warmed = True


@functools.cache
def _shipped_dbc() -> Database:
    """The shipped DBC, parsed once per worker process (each run and its verdict read it)."""
    return load_dbc()


RUN_LOGGERS = ("dsg_hil", "ecu_stub")  # what a run logs: a fault's rejected frames, a tick answered late ...


@contextlib.contextmanager
def runs_quiet() -> Iterator[None]:
    """The runs' warnings not printed while the block runs (errors still are). A sweep's runs count them in each
    summary and keep them in the logs; printed (by Python's last-resort handler) they interleaved with the
    sweep's progress on the terminal, a few hundred lines per faulted run."""
    loggers = [logging.getLogger(name) for name in RUN_LOGGERS]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


def _warm_in_worker() -> None:
    try:
        from distributed import Lock, get_worker  # noqa: PLC0415

        get_worker()
    except (ImportError, ValueError):
        warm()
        return
    for name in RUN_LOGGERS:  # a Dask worker runs nothing but runs: quiet for good (see runs_quiet)
        logging.getLogger(name).setLevel(logging.ERROR)
    with Lock(WARM_LOCK):
        warm()


def _run(task: dict[str, Any], log: Path | None) -> tuple[dict[str, Any], dict[str, Any]]:
    """One run of ``task`` (its log to ``log``): the summary JSON, and what the worker measures besides: the top
    true speed, the top desired speed, the driver's pedal when the vehicle stopped, whether it stopped in a fault
    window."""
    scenario = parse_scenario(task["scenario"], task["run_id"])
    params = with_overrides(load_params(), task["params"], origin="sweep") if task["params"] else None
    peak = [float("-inf")]
    db = _shipped_dbc()
    unexplained = UnexplainedFault(fault_windows((parse_fault(f) for f in task["faults"]), db))

    def track(runner: Any) -> None:
        peak[0] = max(peak[0], runner.out.v)
        unexplained.update(runner.plant.state.t, runner.summary.tcu_state)

    config = RunConfig(scenario=scenario, params=params, faults=task["faults"], log=log, on_period=track, dbc=db,
                       **config_for(task["controller"]))
    with open_run(config) as run:
        summary = run.run().as_json()
    stop = summary.get("stop_time_s")
    return summary, {"v_max_mps": peak[0] if peak[0] > float("-inf") else None,
                     "fault_unexplained_s": round(unexplained.seconds, 3),
                     "v_desired_max_mps": max(e.desired_speed_mps for e in scenario.driver),
                     "brake_at_stop": None if stop is None else pedal_while_stopping(scenario, stop),
                     "stop_in_fault_window": stop is not None and in_windows(stop, unexplained.windows)}


def pedal_while_stopping(scenario: Scenario, stop: float) -> float:
    """The driver's highest pedal from ``stop`` over the time the summary needs to call a vehicle at rest stopped
    (:data:`~dsg_hil.results.thresholds.STOP_MIN_S`): a vehicle that stops as the driver brakes in that time was
    stopped by him (a stop-and-go driver released the brake at 125.319 s and pressed it again at 125.358 s; the
    pedal at 125.321 s alone said nobody braked)."""
    later = (event.brake for event in scenario.driver if stop < event.t_s <= stop + STOP_MIN_S)
    return max([scenario.driver_at(stop).brake, *later])


def run_task(task: dict[str, Any], keep_log: bool = False) -> dict[str, Any]:
    """Run ``task``; never raises for a run that fails (its row says ``verdict = "error"`` and why). The log is
    written with ``keep_log`` only; a violating or failed run is run again with its log (lockstep: the same run)."""
    _warm_in_worker()
    t0 = time.perf_counter()
    inputs = {f"in.{k}": v if not isinstance(v, list) else ";".join(map(str, v)) for k, v in task["inputs"].items()}
    base = {"run_id": task["run_id"], "index": task["index"], **inputs, "code": code_digest()}
    with tempfile.TemporaryDirectory(prefix="dsg-hil-sweep-") as tmp:
        log = Path(tmp) / "run.log"
        try:
            summary, measured = _run(task, log if keep_log else None)
        except Exception as exc:  # noqa: BLE001 - a failed run is a result of the sweep, not its end
            row = {**base, "verdict": "error", "violations": "", "error": f"{type(exc).__name__}: {exc}",
                   "wall_s": time.perf_counter() - t0}
            if not keep_log:
                with contextlib.suppress(Exception):
                    _run(task, log)
            return {"run_id": task["run_id"], "row": row, "summary": None, "log": _read(log),
                    "traceback": traceback.format_exc(), "task": task}
        row = {**base, **summary_row(summary), **measured, "latent_x": largest_multiple(task["inputs"].get("latent"))}
        peak_T = row.get("max_plate_temp_c")
        row["margin_c"] = None if peak_T is None else task["limits"]["plate_temp_c"] - peak_T
        found = violations(row, task["limits"])
        row |= {"verdict": verdict(row, found), "violations": ",".join(found), "error": None,
                "wall_s": time.perf_counter() - t0}
        if found and not keep_log:
            _run(task, log)
        return {"run_id": task["run_id"], "row": row, "summary": summary,
                "log": _read(log) if found or keep_log else None, "traceback": None, "task": task}


def _read(path: Path) -> bytes | None:
    """The log, gzip-compressed (None if there is none)."""
    return gzip.compress(path.read_bytes()) if path.exists() else None
