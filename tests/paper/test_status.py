"""Fitted vs predicted: the report's status of each paper number comes from the calibrations' own definition, and
that definition is what the fits consume (not a list kept beside them)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from dsg_hil.paper import calibration
from dsg_hil.paper.calibration import (CALIBRATIONS, MU_TARGETS, PRESSURE_TARGETS, RISE_KEYS, TIMELINE_TARGETS,
                                       calibrate_stribeck, fitted_by, reduced_creep, timeline_residuals)
from dsg_hil.paper.report.paper import PAPER, compare, tally, tally_text

BY_KEY = {p.key: p for p in PAPER}


def test_every_calibrated_parameter_belongs_to_a_calibration(params):
    calibrated = {key for key, (source, _) in params.provenance.items() if source == "calibrated"}
    assert calibrated, "the shipped file tags some values calibrated"
    assert calibrated <= {q for c in CALIBRATIONS for q in c.quantities}


def test_every_target_is_a_paper_number_with_the_papers_value():
    for c in CALIBRATIONS:
        assert set(c.targets) <= set(BY_KEY), c.name
    for t in TIMELINE_TARGETS + MU_TARGETS + PRESSURE_TARGETS:
        assert BY_KEY[t.key].paper == t.published, t.key
    assert all(BY_KEY[k].paper is not None for k in RISE_KEYS)


def test_status_follows_the_calibrations():
    rows = compare({})
    for r in rows:
        cal = fitted_by(r["key"])
        assert r["status"] == ("predicted" if cal is None else "fitted"), r["key"]
        assert (r["fitted_by"] is None) == (cal is None)
        if cal is not None:
            assert cal.name in r["fitted_by"] and all(q in r["fitted_by"] for q in cal.quantities)
    targets = {k for c in CALIBRATIONS for k in c.targets}
    assert sum(r["status"] == "fitted" for r in rows) == len(targets & set(BY_KEY))


def test_the_stribeck_fit_consumes_its_targets(params, monkeypatch):
    """Move a published mu_CH: the fitted amplitude moves. The number is fitted, not predicted."""
    base = calibrate_stribeck(params).A_stribeck
    for i in range(len(MU_TARGETS)):
        moved = tuple(replace(t, published=t.published + 0.002) if j == i else t for j, t in enumerate(MU_TARGETS))
        monkeypatch.setattr(calibration, "MU_TARGETS", moved)
        assert calibrate_stribeck(params).A_stribeck != pytest.approx(base, rel=1e-3), MU_TARGETS[i].key
    monkeypatch.undo()


def test_the_timeline_fit_consumes_each_timeline_target(params, monkeypatch):
    r = reduced_creep(params, dt=0.1)
    base = timeline_residuals(r)
    for i, target in enumerate(TIMELINE_TARGETS):
        moved = tuple(replace(t, published=t.published + t.tolerance) if j == i else t
                      for j, t in enumerate(TIMELINE_TARGETS))
        monkeypatch.setattr(calibration, "TIMELINE_TARGETS", moved)
        changed = timeline_residuals(r) != base
        assert changed.tolist() == [j == i for j in range(len(changed))], target.key
    monkeypatch.undo()


def test_zero_residual_dof_in_section_vb_and_three_in_the_rises():
    by_name = {c.name: c for c in CALIBRATIONS}
    assert by_name["vehicle thermal"].independent_targets == len(TIMELINE_TARGETS) - 1  # 174 s = 43.5 + 130.5 s
    assert by_name["vehicle thermal"].residual_dof == 0
    assert by_name["rig heat transfer"].residual_dof == len(RISE_KEYS) - 1


def test_summary_line_counts_fitted_and_predicted_apart():
    report = {"creep_time_s": 170.0, "stop_time_s": 170.0, "stop_reason": "STOPPED_OVERHEAT",
              "slip_time_s": {"CL": 43.5, "CH": 110.0}, "max_plate_temp_c": {"CL": 249.0, "CH": 251.0}}
    rows = compare(report)
    t = tally(rows)
    vb = [r for r in rows if r["section"] == "V.B"]
    assert t["V.B"]["numbers"] == len(vb)
    assert t["V.B"]["fitted"]["count"] + t["V.B"]["predicted"]["count"] == len(vb)
    assert t["V.B"]["predicted"] == {"count": 2, "pass": 1, "miss": 1, "n/a": 0}  # the two 250 degC bounds
    assert t["V.B"]["fitted"]["pass"] == 2 and t["V.B"]["fitted"]["miss"] == 1  # slip CH 110 s is outside 15 %
    line = tally_text(t)
    assert line.startswith(f"Section V.B: {len(vb)} numbers, {t['V.B']['fitted']['count']} fitted (2 pass, 1 miss, ")
    assert "2 predicted (1 pass, 1 miss)" in line and "Section III.C: " in line


def test_a_log_that_ends_before_any_stop_says_so():
    report = {"creep_time_s": 20.0, "stop_time_s": None, "stop_reason": "end_of_record",
              "slip_time_s": {"CL": 20.0, "CH": 0.0}}
    rows = {r["key"]: r for r in compare(report)}
    for key in ("creep_time_s", "slip_time_s.CL", "slip_time_s.CH"):
        assert rows[key]["result"] == "miss" and "ends before any stop" in rows[key]["reason"], key
        assert "hands over" not in rows[key]["reason"]
