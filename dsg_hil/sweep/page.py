"""The sweep's page: ``OUT/sweep.md`` with the verdict, each violation with the exact ``dsg-hil run`` that reproduces
it (its scenario and parameter files written under ``OUT/violations/<run_id>/``), the worst runs, and the figures
(matplotlib, if installed): the peak true plate temperature against each input, the margin histogram, and the
worst run's timeline (re-run here in lockstep with the truth recorded: the same run, bit for bit)."""

from __future__ import annotations

import math
import shlex
from collections.abc import Callable, Mapping, Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

from ..physics.params import load_params
from .code import code_digest, code_note
from .engine import SweepResult
from .space import Space
from .verdict import latent_counts

__all__ = ["HANDOVER_DRIVABLE_PCT", "ROLLBACK_DRIVABLE_MPS", "drivability_lines", "params_toml", "repro_files",
           "write_page"]

WORST = 10  # rows in the table of the hottest runs
ROLLBACK_DRIVABLE_MPS = 0.01  # the drivability target: at most 10 mm/s backwards at a brake release
HANDOVER_DRIVABLE_PCT = 20.0  # ... and the speed within +-20 % of the desired speed through handovers


def params_toml(overrides: Mapping[str, float]) -> str:
    """A parameter file layered on the shipped one (``dsg-hil run --params``) giving the overridden keys."""
    params: Any = load_params()
    tables: dict[str, list[str]] = {}
    for key, value in overrides.items():
        *path, name = key.split(".")
        obj = params
        for part in path:
            obj = getattr(obj, part)
        unit = {f.name: f.metadata.get("unit") for f in fields(obj)}[name]
        tables.setdefault(".".join(path), []).append(
            f'{name} = {{ value = {float(value)!r}, unit = "{unit}", source = "assumed", why = "dsg-hil sweep" }}')
    return "".join(f"[{t}]\n" + "\n".join(lines) + "\n\n" for t, lines in tables.items())


def repro_files(task: Mapping[str, Any], where: Path, out: Path) -> str:
    """Write the run's scenario (and parameter) file under ``where``; the ``dsg-hil run`` command that repeats it
    (paths relative to ``out``, where the page is)."""
    where.mkdir(parents=True, exist_ok=True)
    (where / "scenario.toml").write_text(task["scenario"], encoding="utf-8")
    argv = ["dsg-hil", "run", "--scenario", str((where / "scenario.toml").relative_to(out))]
    if task["params"]:
        (where / "params.toml").write_text(params_toml(task["params"]), encoding="utf-8")
        argv += ["--params", str((where / "params.toml").relative_to(out))]
    for fault in task["faults"]:
        argv += ["--fault", fault]
    command = shlex.join(argv)
    (where / "command.sh").write_text(command + "\n", encoding="utf-8")
    return command


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return "-" if math.isnan(value) else f"{value:.4g}"
    return "-" if value is None else str(value)


def _controller_note(controller: Mapping[str, Any]) -> str:
    if controller["kind"] == "ecu-stub" and "calibration" not in controller:
        return "the bundled ecu-stub"
    if controller["kind"] == "ecu-stub":
        return f"ecu-stub with the calibration {controller.get('calibration_file')} (the command runs the default)"
    if controller["kind"] == "python":
        return f"the Python controller {controller['target']} (in dsg_hil.testing.run_plant)"
    return f"the controller process {shlex.join(controller['argv'])}"


def write_page(space: Space, result: SweepResult, record: Callable[[str], Mapping[str, Any]]) -> Path:
    """Write ``OUT/sweep.md`` (and figures, reproducing files); ``record(run_id)``: the run's stored record
    (:meth:`dsg_hil.sweep.results.ResultStore.record`)."""
    out = result.out
    rows = result.rows
    ok = [r for r in rows if r.get("max_plate_temp_c") is not None]
    worst = sorted(ok, key=lambda r: -float(r["max_plate_temp_c"]))[:WORST]
    lines = [f"# Sweep: {space.name}", "",
             f"Space `{space.origin}`: {len(rows)} runs ({result.ran} run now, {result.skipped} resumed), sampler "
             f"{space.sampler}, seed {space.seed}; controller: {_controller_note(space.controller)}. "
             f"Wall time {result.wall_s:.0f} s.", "",
             "Judged on the plant's truth, limits: " + ", ".join(f"{k} {v:g}" for k, v in space.limits.items()),
             ""]
    here = code_digest()
    note = code_note(rows, here)
    lines += [f"**Code: {note}.**" if note else f"Code: all runs by {here} (`dsg_hil` and `ecu_stub`: "
              f"dsg_hil.sweep.code).", ""]
    violating = result.violations
    errors = [r for r in rows if r.get("verdict") == "error"]
    outside = [r for r in rows if r.get("verdict") == "outside_range"]
    lines += [f"**Verdict: {len(violating)} violating run(s)**, {len(errors)} failed run(s), {len(outside)} run(s) "
              "outside the operating range without a violation (not covered by the claim).", ""]
    lines += latent_lines(rows, violating)
    if result.search:
        lines += ["## Search", "", *(f"- {k}: {_fmt(v)}" for k, v in result.search.items()), ""]
    if violating:
        lines += ["## Violations", ""]
        for row in violating:
            task = record(row["run_id"])["task"]
            command = repro_files(task, out / "violations" / row["run_id"], out)
            lines += [f"- `{row['run_id']}`: **{row['violations']}**; peak plate {_fmt(row.get('max_plate_temp_c'))} "
                      f"degC, roll-back {_fmt(row.get('rollback_m'))} m, top speed {_fmt(row.get('v_max_mps'))} m/s, "
                      f"stop {row.get('stop_reason')}", f"  `{command}`"]
        lines.append("")
    if errors:
        lines += ["## Failed runs", "", *(f"- `{r['run_id']}`: {r.get('error')}" for r in errors), ""]
    inputs = [c for c in (rows[0] if rows else {}) if c.startswith("in.")]
    if worst:
        columns = ["run_id", "max_plate_temp_c", "margin_c", "time_above_limit_s.CL", "time_above_limit_s.CH",
                   "stop_reason", *inputs]
        lines += ["## Hottest runs (true plate temperature)", "", *_table(columns, worst)]
    lines += drivability_lines(ok, inputs)
    lines += _figures(space, out, ok, inputs, record(worst[0]["run_id"])["task"] if worst else None)
    page = out / "sweep.md"
    page.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return page


def latent_lines(rows: Sequence[Mapping[str, Any]], violating: Sequence[Mapping[str, Any]]) -> list[str]:
    """The verdict's count of the runs by their latent sensor faults (:func:`~.verdict.latent_counts`), all and
    violating; nothing if no run has one."""
    if not latent_counts(rows):
        return []
    return [f"Latent sensor faults: of the {len(rows)} runs, {latent_counts(rows)}"
            + (f"; of the {len(violating)} violating, {latent_counts(violating) or 'none has one'}" if violating
               else "") + ".", ""]


def drivability_lines(rows: Sequence[Mapping[str, Any]], inputs: list[str]) -> list[str]:
    """The page's drivability section: reported, not judged (the verdict's roll-back limit is a distance). The runs
    whose fastest backward speed (``rollback_mps``, at any time of the run: brake releases, fault reactions)
    exceeds :data:`ROLLBACK_DRIVABLE_MPS`, and those whose speed left :data:`HANDOVER_DRIVABLE_PCT` of the desired
    through a handover (``handover_deviation_pct``), the worst first, with how many of them left it through a
    handover without the driver's pedal in its window (``handover_deviation_unbraked_pct``: a light drag, under the
    TCU's "pressed" threshold, slows the vehicle whatever the handover does)."""
    rolled = sorted((r for r in rows if r.get("rollback_mps") is not None
                     and -float(r["rollback_mps"]) > ROLLBACK_DRIVABLE_MPS), key=lambda r: float(r["rollback_mps"]))
    judged = [r for r in rows if r.get("handover_deviation_pct") is not None]
    off = sorted((r for r in judged if float(r["handover_deviation_pct"]) > HANDOVER_DRIVABLE_PCT),
                 key=lambda r: -float(r["handover_deviation_pct"]))
    unbraked = [r for r in off if r.get("handover_deviation_unbraked_pct") is not None
                and float(r["handover_deviation_unbraked_pct"]) > HANDOVER_DRIVABLE_PCT]
    lines = ["## Drivability (reported, not judged)", "",
             f"Runs rolling backwards faster than {ROLLBACK_DRIVABLE_MPS * 1000:g} mm/s at some time (the drivability "
             f"target at a brake release; here at any time, fault reactions included): **{len(rolled)} of "
             f"{len(rows)}**.", ""]
    if rolled:
        lines += _table(["run_id", "rollback_mps", "rollback_m", *inputs], rolled[:WORST])
    lines += [f"Runs whose speed left ±{HANDOVER_DRIVABLE_PCT:g} % of the desired speed through a handover (one "
              f"begun within the band; to 1 s after it): **{len(off)} of the {len(judged)} with such a "
              f"handover**; through a handover without the driver's pedal in its window: **{len(unbraked)}**.", ""]
    if off:
        lines += _table(["run_id", "handover_deviation_pct", "handover_deviation_unbraked_pct",
                         "max_speed_creep_mps", *inputs], off[:WORST])
    return lines


def _table(columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """A Markdown table of ``columns`` of ``rows`` (:func:`_fmt` cells), and the blank line after it."""
    return ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns),
            *("| " + " | ".join(_fmt(r.get(c)) for c in columns) + " |" for r in rows), ""]


def _figures(space: Space, out: Path, rows: Sequence[Mapping[str, Any]], inputs: list[str],
             worst: Mapping[str, Any] | None) -> list[str]:
    """The figures (PNG next to the page) and the page's lines showing them."""
    try:
        import matplotlib  # noqa: PLC0415

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # noqa: PLC0415
    except ImportError:
        return ["(No figures: matplotlib is not installed; pip install 'dsg-hil[plots]'.)"]
    if not rows:
        return []
    limit = space.limits["plate_temp_c"]
    numeric = [c for c in inputs if all(isinstance(r.get(c), (int, float)) and not isinstance(r.get(c), bool)
                                        for r in rows) and len({r[c] for r in rows}) > 1]  # the drawn ones
    lines = ["## Figures", ""]
    if numeric:
        ncol = min(3, len(numeric))
        nrow = math.ceil(len(numeric) / ncol)
        fig, axes = plt.subplots(nrow, ncol, figsize=(4 * ncol, 3 * nrow), squeeze=False)
        for ax, column in zip(axes.flat, numeric):
            ax.scatter([r[column] for r in rows], [r["max_plate_temp_c"] for r in rows], s=10,
                       c=["tab:red" if r.get("verdict") == "violation" else "tab:blue" for r in rows])
            ax.axhline(limit, color="k", lw=0.8, ls="--")
            ax.set_xlabel(column.removeprefix("in."))
            ax.set_ylabel("max plate T (truth) [degC]")
        for ax in list(axes.flat)[len(numeric):]:
            ax.set_visible(False)
        fig.tight_layout()
        fig.savefig(out / "max_temp_vs_inputs.png", dpi=90)
        plt.close(fig)
        lines += ["![peak plate temperature against each input](max_temp_vs_inputs.png)", ""]
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.hist([r["margin_c"] for r in rows if r.get("margin_c") is not None], bins=20)
    ax.axvline(0.0, color="k", lw=0.8, ls="--")
    ax.set_xlabel(f"margin to {limit:g} degC (truth) [K]")
    ax.set_ylabel("runs")
    fig.tight_layout()
    fig.savefig(out / "margin_histogram.png", dpi=90)
    plt.close(fig)
    lines += ["![margin histogram](margin_histogram.png)", ""]
    if worst is not None:
        lines += _timeline(plt, worst, out, limit)
    return lines


def _timeline(plt: Any, task: Mapping[str, Any], out: Path, limit: float) -> list[str]:
    """The worst run again, in this process, its truth each control period: speed and plate temperatures
    (Figs. 9 and 12 of the paper)."""
    from ..physics.params import with_overrides  # noqa: PLC0415
    from ..sim.run import RunConfig, open_run  # noqa: PLC0415
    from ..sim.scenario import parse_scenario  # noqa: PLC0415
    from .controllers import config_for  # noqa: PLC0415
    from .worker import runs_quiet  # noqa: PLC0415

    params = with_overrides(load_params(), task["params"], origin="sweep") if task["params"] else None
    config = RunConfig(scenario=parse_scenario(task["scenario"], task["run_id"]), params=params,
                       faults=task["faults"], truth=True, **config_for(task["controller"]))
    with runs_quiet(), open_run(config) as run:
        run.run()
    truth = run.truth()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    top.plot(truth["t"], truth["v"], label="v (truth)")
    top.set_ylabel("speed [m/s]")
    for name in ("T_CL", "T_CH"):
        bottom.plot(truth["t"], truth[name], label=f"{name} (truth)")
    bottom.axhline(limit, color="k", lw=0.8, ls="--")
    bottom.set_ylabel("plate temperature [degC]")
    bottom.set_xlabel("t [s]")
    bottom.legend()
    fig.tight_layout()
    fig.savefig(out / "worst_run.png", dpi=90)
    plt.close(fig)
    return [f"Worst run `{task['run_id']}` (re-run in lockstep):", "", "![worst run](worst_run.png)", ""]
