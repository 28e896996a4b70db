"""``dsg-hil report``: the paper's figures and numbers beside dsg-hil's, from the validation rig and a creep log.

Entry point: :func:`write_report`. The creep part always comes from a decoded bus log (:mod:`.log`), whether
``dsg-hil report`` recorded it itself or it was given (``--from-log``): one code path.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from ..validation import CaseResult, validation_json
from .log import CreepRecord
from .paper import compare

FIGURE_DIR = "figures"


def report_json(record: CreepRecord, cases: list[CaseResult]) -> dict:
    """report.json: the creep numbers of the log, the validation cases, and the paper table."""
    data = {**record.metrics, **validation_json(cases),
            "log": {"path": record.source, "frames": record.frames, "tcu_status": record.has_status}}
    data["paper_vs_dsg_hil"] = compare(data)
    return data


def write_report(out: Path, record: CreepRecord, cases: list[CaseResult],
                 progress: Callable[[str], None] = lambda _: None) -> dict:
    """Figures (Figs. 3-5 and 8-12), report.md and report.json into ``out``; returns report.json's content."""
    from ..plots import validation_figures
    from .figures import creep_figures
    from .page import write_page
    figdir = out / FIGURE_DIR
    figures = validation_figures(cases, figdir) + creep_figures(record, figdir)
    for path in figures:
        progress(f"wrote {path}")
    data = report_json(record, cases)
    (out / "report.json").write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    progress(f"wrote {out / 'report.json'}")
    progress(f"wrote {write_page(out / 'report.md', data, figures)}")
    return data
