"""``dsg-hil sweep --search``: falsification. Instead of sampling, Optuna's TPE sampler (seeded with the space's
seed) proposes runs from the same space to maximise the space's objective (``[search] objective``: the peak true
plate temperature by default; :data:`dsg_hil.sweep.verdict.OBJECTIVES`), as many in flight as the Dask cluster has
workers (a space's latent faults, :mod:`.latent`, are drawn per trial index, not proposed). It stops at the first
violating run or after ``budget`` runs, and writes the counterexample as a runnable
scenario (``OUT/counterexample/``: scenario, parameters, the ``dsg-hil run`` command)."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ..common.errors import InputError
from .engine import Progress, SweepResult, open_client, result_of, submit
from .page import repro_files
from .results import ResultStore
from .space import Dist, Space
from .verdict import objective_value

__all__ = ["run_search", "suggest"]


def suggest(trial: Any, name: str, dist: Dist) -> Any:
    """The trial's value of one input: uniform over its range, normal over mean +- 3 sd, choice categorical."""
    if dist.kind == "uniform":
        lo, hi = dist.args
        return trial.suggest_float(name, lo, hi) if hi > lo else lo
    if dist.kind == "normal":
        mean, sd = dist.args
        return trial.suggest_float(name, mean - 3.0 * sd, mean + 3.0 * sd)
    if dist.kind == "choice" and dist.free:
        index = trial.suggest_categorical(name, list(range(len(dist.args))))
        return dist.args[index]
    return dist.args[0]


def run_search(space: Space, out: str | Path, *, budget: int | None = None, workers: int | None = None,
               scheduler: str | None = None, resume: bool = False, keep_logs: bool = False,
               progress: Callable[[str], None] | None = None) -> SweepResult:
    """Search ``space`` for a violation: at most ``budget`` (default: the space's ``n``) runs."""
    try:
        import optuna  # noqa: PLC0415
    except ImportError as exc:
        raise InputError("dsg-hil sweep --search needs Optuna: pip install 'dsg-hil[sweep]'") from exc
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    budget = space.n if budget is None else budget
    t0 = time.monotonic()
    store = ResultStore(out, resume=resume)
    sampler = optuna.samplers.TPESampler(seed=space.seed, n_startup_trials=max(4, budget // 4))
    study = optuna.create_study(direction="maximize", sampler=sampler)
    best: dict[str, Any] = {}
    found: Mapping[str, Any] | None = None
    launched = 0
    link = None
    try:
        with open_client(workers, scheduler, progress) as (client, link):
            from distributed import as_completed  # noqa: PLC0415

            parallel = max(1, len(client.scheduler_info().get("workers", {})))
            bar = Progress(budget, progress, link)
            trials: dict[str, tuple[Any, dict[str, Any]]] = {}

            def launch() -> Any:
                nonlocal launched
                trial = study.ask()
                values = space.with_latent(launched, {k: suggest(trial, k, d) for k, d in space.inputs.items()})
                task = space.task(launched, values)
                task["run_id"] = "s" + task["run_id"][1:]
                launched += 1
                future = submit(client, [task], keep_logs)[0]
                trials[future.key] = (trial, task)
                return future

            pending = as_completed([launch() for _ in range(min(parallel, budget))])
            for future in pending:
                trial, task = trials.pop(future.key)
                result = result_of(future, task)
                row = result["row"]
                value = objective_value(row, space.objective)
                study.tell(trial, value if value > float("-inf") else None,
                           state=None if value > float("-inf") else optuna.trial.TrialState.FAIL)
                store.add(result)
                bar.update(row)
                if value > best.get("value", float("-inf")):
                    best = {"value": value, "run_id": row["run_id"]}
                if row.get("verdict") == "violation":
                    found = result
                    break
                if launched < budget:
                    pending.add(launch())
            if found is not None:
                client.cancel(list(pending.futures))  # the runs still in flight: not needed
    finally:
        store.flush()
    counterexample = None
    if found is not None:
        counterexample = out_path = Path(out) / "counterexample"
        command = repro_files(found["task"], out_path, Path(out))
        if progress is not None:
            progress(f"search: counterexample {found['run_id']} ({found['row']['violations']}): {command}")
    summary = {"objective": space.objective, "budget": budget, "runs": launched, "best": best.get("value"),
               "best_run": best.get("run_id"), "counterexample": found["run_id"] if found else None}
    return SweepResult(Path(out), store.rows(), launched, 0, time.monotonic() - t0, link, counterexample, summary)
