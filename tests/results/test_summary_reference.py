"""The summary reference page (docs/reference/summary.md) against the summary itself: the same keys in the same
order as a real run's ``as_json()`` (a run with an input outside the operating range, which adds the one key a run
inside it lacks), and every ``stop_reason`` value the code can produce documented."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from dsg_hil.results.summary import CreepMetrics
from dsg_hil.sim import run as run_module
from dsg_hil.sim.run import RunConfig, open_run

from ..source import definition

README = Path(__file__).resolve().parents[2] / "docs" / "reference" / "summary.md"
HEADING = "# The summary, key by key"


def _section() -> str:
    text = README.read_text(encoding="utf-8")
    assert HEADING in text
    body = text.split(HEADING, 1)[1]
    return re.split(r"^#{1,3} ", body, maxsplit=1, flags=re.MULTILINE)[0]


def _tables(section: str) -> dict[str, list[list[str]]]:
    """The section's tables by their first header cell: the rows' cells, separator and header dropped."""
    tables: dict[str, list[list[str]]] = {}
    current: list[list[str]] | None = None
    for line in section.splitlines():
        if not line.startswith("|"):
            current = None
            continue
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if current is None:
            current = tables.setdefault(cells[0], [])
        elif not set(cells[0]) <= set("-: "):
            current.append(cells)
    return tables


def _code(cell: str) -> str:
    match = re.fullmatch(r"`([^`]+)`", cell)
    assert match, f"not a `key` cell: {cell!r}"
    return match.group(1)


OUTSIDE = {"vehicle.m": 12544.0}  # above the operating range's 11,760 kg (dsg_hil.sim.operating_range)


@pytest.fixture(scope="module")
def summary_keys() -> dict[str, list[str]]:
    keys = {}
    for name, params in (("inside", None), ("outside", OUTSIDE)):
        with open_run(RunConfig(duration=1.0, params=params)) as run:
            keys[name] = list(run.run().as_json())
    return keys


def test_the_table_has_every_key_in_order(summary_keys):
    rows = _tables(_section())["key"]
    assert all(len(row) == 4 and all(row) for row in rows), "each row: key, unit, meaning, null when"
    assert [_code(row[0]) for row in rows] == summary_keys["outside"]
    absent = [_code(row[0]) for row in rows if row[3].startswith("absent")]  # documented as absent, not null
    assert absent == ["outside_range"]
    assert summary_keys["inside"] == [key for key in summary_keys["outside"] if key not in absent]


def _identifiers(node: ast.AST) -> set[str]:
    """The string constants under ``node`` that are identifiers (a docstring is not)."""
    return {n.value for n in ast.walk(node) if isinstance(n, ast.Constant) and isinstance(n.value, str)
            and n.value.isidentifier()}


def test_every_stop_reason_is_documented():
    """The values ``_stop_reason`` (a run ended early) and ``CreepMetrics.as_json`` (assigned to its ``reason``:
    the creep's) can give."""
    early = _identifiers(definition(run_module._stop_reason))
    as_json = definition(CreepMetrics.as_json)
    creep = set().union(*(_identifiers(node.value) for node in ast.walk(as_json) if isinstance(node, ast.Assign)
                          and any(isinstance(t, ast.Name) and t.id == "reason" for t in node.targets)))
    assert "peer_lost" in early and "end_of_record" in creep  # the search finds them
    documented = [_code(row[0]) for row in _tables(_section())["value"]]
    assert sorted(documented) == sorted(early | creep)


def test_the_failure_metrics_follow_their_rows_in_the_table():
    """The keys no average can hide a failure in, on a hand-built record: each as its row on that page defines it."""
    from .test_summary import feed, out

    rows = {_code(row[0]): row[2] for row in _tables(_section())["key"]}
    assert "while creep is requested" in rows["max_speed_creep_mps"] and "FAULT" in rows["rollback_guarded_m"]
    m = CreepMetrics()
    t = feed(m, 1.0, 0.0, creep=False, v=0.5)  # not requested: neither speed nor roll-back counts
    t = feed(m, 1.0, t, creep=False, v=-0.05)
    m.status(t, 5.0, 0.0, 100.0, 100.0, out(t))  # FAULT from here: roll-back is the TCU's
    t = feed(m, 1.0, t, creep=False, v=-0.02)
    m.status(t, 5.0, 0.0, 100.0, 100.0, out(t))
    m.status(t + 0.1, 0.0, 0.0, 100.0, 247.5, out(t + 0.1))  # FAULT ended: 1.1 s of it
    t = feed(m, 1.0, t, creep=True, desired=0.1, v=-0.01, T_CL=246.0)  # creep requested: counts
    t = feed(m, 1.0, t, creep=True, desired=0.1, v=0.3)
    j = m.as_json()
    assert j["max_speed_creep_mps"] == 0.3 and j["overspeed_mps"] == pytest.approx(0.2)
    # roll-back by the trapezoid between samples: a speed step counts half a sample at each speed, so the runs of
    # 1 s at -0.05, -0.02, -0.01 m/s give 0.08 m less half a sample of -0.05 at the start and of -0.01 at the end;
    # guarded (from the first -0.02 sample on): 0.03 m, plus half a sample of -0.05 (its first interval is the
    # trapezoid from -0.05) less half a sample of -0.01 at the end
    from .test_summary import DT

    assert j["rollback_m"] == pytest.approx(0.08 - 0.5 * DT * (0.05 + 0.01), abs=1e-4)
    assert j["rollback_guarded_m"] == pytest.approx(0.03 + 0.5 * DT * (0.05 - 0.01), abs=1e-4)
    assert j["fault_time_s"] == pytest.approx(1.1)
    assert j["min_margin_c"] == {"truth": 4.0, "predicted": 2.5}
