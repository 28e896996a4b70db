"""``dsg-hil sweep --search``: falsification. Instead of sampling, Optuna's TPE sampler (seeded with the space's
seed) proposes runs from the same space to maximise the space's objective (``[search] objective``: the peak true
plate temperature by default; :data:`dsg_hil.sweep.verdict.OBJECTIVES`), as many in flight as the Dask cluster has
workers (a space's latent faults, :mod:`.latent`, are drawn per trial index, not proposed). It stops at the first
violating run or after ``budget`` runs, and writes the counterexample as a runnable
scenario (``OUT/counterexample/``: scenario, parameters, the ``dsg-hil run`` command).

``resume``: the trials already in ``OUT`` (a search killed midway) are told to the new study first, each with the
parameters :func:`suggest` gives its stored inputs (:func:`stored_trials`), then the search goes on from there: the
new trials take the run indices not yet stored (``s<index>``; their latent faults are those an uninterrupted search
draws for the same indices), the stored ones count against the budget, the best stays the stored best, and a stored
violation is the counterexample with nothing run. A resumed search proposes other trials than an uninterrupted one
would (the sampler's state is not stored, only its trials): nothing stored is run again or lost, but the same
space, seed and budget need not end with the same trials."""

from __future__ import annotations

import itertools
import time
import warnings
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from ..common.errors import InputError
from .engine import Progress, SweepResult, open_client, result_of, resumed_n, start_manifest, submit
from .page import repro_files
from .results import ResultStore
from .space import Dist, Space
from .verdict import objective_value

__all__ = ["run_search", "search_study", "stored_trials", "suggest"]


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


def _replayed(space: Space, inputs: Mapping[str, Any], optuna: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    """The parameters and distributions :func:`suggest` gives a trial whose inputs are ``inputs`` (a choice as its
    index; the latent faults, drawn by index, are none of them). ValueError if an input is not the space's."""
    params: dict[str, Any] = {}
    for name, dist in space.inputs.items():
        if dist.kind == "choice" and dist.free:
            params[name] = [i for i, v in enumerate(dist.args) if v == inputs[name]][0]
        elif name in inputs:
            params[name] = inputs[name]
    trial = optuna.trial.FixedTrial(params)
    with warnings.catch_warnings():  # a value out of its range: FixedTrial warns, create_trial raises
        warnings.simplefilter("ignore")
        for name, dist in space.inputs.items():
            if suggest(trial, name, dist) != inputs[name]:
                raise ValueError(f"inputs.{name} = {inputs[name]!r} is not {dist.kind} {list(dist.args)}")
    return dict(trial.params), dict(trial.distributions)


def stored_trials(space: Space, store: ResultStore) -> list[tuple[int, Any, dict[str, Any]]]:
    """The search's trials already in ``store``, by run index: (index, the Optuna trial to tell the study, the
    stored record: run_id, row, task). A stored input the space cannot have proposed is an :class:`InputError`."""
    import optuna  # noqa: PLC0415

    trials = []
    for run_id, row in store.done.items():
        record = store.record(run_id)
        task = record.get("task") or {}
        inputs = task.get("inputs") or {k.removeprefix("in."): v for k, v in row.items() if k.startswith("in.")}
        value = objective_value(row, space.objective)
        try:
            params, distributions = _replayed(space, inputs, optuna)
            trial = optuna.trial.create_trial(
                params=params, distributions=distributions, value=value if value > float("-inf") else None,
                state=optuna.trial.TrialState.COMPLETE if value > float("-inf") else optuna.trial.TrialState.FAIL)
        except (KeyError, IndexError, ValueError) as exc:
            raise InputError(f"--resume: {store.runs / (run_id + '.json')}: not a trial of {space.origin}'s search "
                             f"({type(exc).__name__}: {exc}): give another --out") from exc
        trials.append((int(row.get("index", task.get("index", 0))), trial, {**record, "task": task}))
    return sorted(trials, key=lambda t: t[0])


def search_study(space: Space, budget: int, stored: Iterable[Any] = ()) -> Any:
    """The Optuna study of a search of ``budget`` runs (TPE, seeded with the space's seed), told the ``stored``
    trials (:func:`stored_trials`) before it proposes any."""
    import optuna  # noqa: PLC0415

    sampler = optuna.samplers.TPESampler(seed=space.seed, n_startup_trials=max(4, budget // 4))
    study = optuna.create_study(direction="maximize", sampler=sampler)
    for trial in stored:
        study.add_trial(trial)
    return study


def run_search(space: Space, out: str | Path, *, budget: int | None = None, workers: int | None = None,
               scheduler: str | None = None, resume: bool = False, keep_logs: bool = False,
               progress: Callable[[str], None] | None = None) -> SweepResult:
    """Search ``space`` for a violation: at most ``budget`` (default: the space's ``n``; on ``resume`` the search's
    own) runs, the stored ones of a resumed search counted (module docstring)."""
    try:
        import optuna  # noqa: PLC0415
    except ImportError as exc:
        raise InputError("dsg-hil sweep --search needs Optuna: pip install 'dsg-hil[sweep]'") from exc
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    budget = resumed_n(space, out, budget, search=True) if resume else (space.n if budget is None else budget)
    t0 = time.monotonic()
    store = ResultStore(out, resume=resume)
    stored = stored_trials(space, store)
    start_manifest(space, out, budget, resume=resume, search=True, progress=progress)
    study = search_study(space, budget, [trial for _, trial, _ in stored])
    best: dict[str, Any] = {}
    found: Mapping[str, Any] | None = None
    for _, _, record in stored:  # what the search had found before it was stopped
        value = objective_value(record["row"], space.objective)
        if value > best.get("value", float("-inf")):
            best = {"value": value, "run_id": record["run_id"]}
        if found is None and record["row"].get("verdict") == "violation":
            found = record
    if stored and progress is not None:
        progress(f"search: {len(stored)} of {budget} trials already in {out} (--resume): told to the study")
    taken = {index for index, _, _ in stored}
    free = (i for i in itertools.count() if i not in taken)  # the indices not yet run, in order
    launched = len(stored)
    link = None
    try:
        if found is None and launched < budget:
            with open_client(workers, scheduler, progress) as (client, link):
                from distributed import as_completed  # noqa: PLC0415

                parallel = max(1, len(client.scheduler_info().get("workers", {})))
                bar = Progress(budget - launched, progress, link)
                trials: dict[str, tuple[Any, dict[str, Any]]] = {}

                def launch() -> Any:
                    nonlocal launched
                    trial, index = study.ask(), next(free)
                    values = space.with_latent(index, {k: suggest(trial, k, d) for k, d in space.inputs.items()})
                    task = space.task(index, values)
                    task["run_id"] = "s" + task["run_id"][1:]
                    launched += 1
                    future = submit(client, [task], keep_logs)[0]
                    trials[future.key] = (trial, task)
                    return future

                pending = as_completed([launch() for _ in range(min(parallel, budget - launched))])
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
    return SweepResult(Path(out), store.rows(), launched - len(stored), len(stored), time.monotonic() - t0, link,
                       counterexample, summary)
