"""``dsg-hil report``: the paper's figures and numbers beside dsg-hil's, from the validation rig and a creep log.

Entry point: :func:`write_report`. The creep part always comes from a decoded bus log (:mod:`.log`), whether
``dsg-hil report`` recorded it itself or it was given (``--from-log``): one code path. The model checks
(:mod:`.model`: hold-out, sensitivity, the Table-I configuration) come from the reduced model and, for Table I,
a second log.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from ..validation import CaseResult, validation_json
from .log import CreepRecord
from .paper import compare, tally, tally_text

if TYPE_CHECKING:
    from ...physics.params import Params
    from ...sim.scenario import Scenario
    from .model import ModelChecks

__all__ = ["FIGURE_DIR", "Comparison", "report_json", "write_report"]

FIGURE_DIR = "figures"


class Comparison:
    """The model checks and the Table-I configuration's run (``table1``: its decoded log, None if not run), with
    the parameters and scenario they were computed for."""

    def __init__(self, checks: ModelChecks, table1: CreepRecord | None, params: Params, scenario: Scenario,
                 name: str = "fitted"):
        self.checks, self.table1, self.params, self.scenario, self.name = checks, table1, params, scenario, name


def report_json(record: CreepRecord, cases: list[CaseResult], comparison: Comparison | None = None) -> dict:
    """report.json: the creep numbers of the log, the validation cases, the paper table (with each number's
    fitted/predicted status and the summary line); with ``comparison`` the model checks and the Table-I run."""
    data = {**record.metrics, **validation_json(cases),
            "log": {"path": record.source, "frames": record.frames, "tcu_status": record.has_status}}
    data["paper_vs_dsg_hil"] = compare(data)
    data["paper_tally"] = tally(data["paper_vs_dsg_hil"])
    data["summary_line"] = tally_text(data["paper_tally"])
    if comparison is not None:
        from .model import TABLE1, configuration_rows, thermal_reason
        c = comparison
        t1 = c.table1
        data["model_checks"] = c.checks.as_json()
        data["configurations"] = {
            "main": c.name,
            TABLE1: None if t1 is None else {"log": t1.source, **{k: t1.metrics[k] for k in (
                "creep_time_s", "slip_time_s", "phases", "max_plate_temp_c", "stop_reason", "stop_time_s")}},
            "why": thermal_reason(c.params, c.checks.table1, c.scenario, t1),
            "section_vb": configuration_rows(data, t1, c.checks)}
    return data


def write_report(out: Path, record: CreepRecord, cases: list[CaseResult],
                 progress: Callable[[str], None] = lambda _: None, comparison: Comparison | None = None) -> dict:
    """Figures (Figs. 3-5 and 8-12; with ``comparison`` the sensitivity map and the configurations' timelines),
    report.md and report.json into ``out``; returns report.json's content."""
    from ..plots import validation_figures
    from .figures import comparison_figures, creep_figures
    from .page import write_page
    figdir = out / FIGURE_DIR
    figures = validation_figures(cases, figdir) + creep_figures(record, figdir)
    if comparison is not None:
        figures += comparison_figures(record, comparison.table1, comparison.checks, figdir, comparison.name)
    for path in figures:
        progress(f"wrote {path}")
    data = report_json(record, cases, comparison)
    (out / "report.json").write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    progress(f"wrote {out / 'report.json'}")
    progress(f"wrote {write_page(out / 'report.md', data, figures)}")
    return data
