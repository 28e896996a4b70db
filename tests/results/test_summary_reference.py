"""The README's "The summary, key by key" against the summary itself: the same keys in the same order as a real
run's ``as_json()``, and every ``stop_reason`` value the code can produce documented."""

from __future__ import annotations

import ast
import inspect
import re
from pathlib import Path

import pytest

from dsg_hil.results.summary import CreepMetrics
from dsg_hil.sim import run as run_module
from dsg_hil.sim.run import RunConfig, open_run

README = Path(__file__).resolve().parents[2] / "README.md"
HEADING = "### The summary, key by key"


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


@pytest.fixture(scope="module")
def summary_keys() -> list[str]:
    with open_run(RunConfig(duration=1.0)) as run:
        return list(run.run().as_json())


def test_the_table_has_every_key_in_order(summary_keys):
    rows = _tables(_section())["key"]
    assert all(len(row) == 4 and all(row) for row in rows), "each row: key, unit, meaning, null when"
    assert [_code(row[0]) for row in rows] == summary_keys


def _identifiers(node: ast.AST) -> set[str]:
    """The string constants under ``node`` that are identifiers (a docstring is not)."""
    return {n.value for n in ast.walk(node) if isinstance(n, ast.Constant) and isinstance(n.value, str)
            and n.value.isidentifier()}


def test_every_stop_reason_is_documented():
    """The values ``_stop_reason`` (a run ended early) and ``CreepMetrics.as_json`` (assigned to its ``reason``:
    the creep's) can give."""
    early = _identifiers(ast.parse(inspect.getsource(run_module._stop_reason)))
    as_json = ast.parse(inspect.getsource(CreepMetrics.as_json).strip())
    creep = set().union(*(_identifiers(node.value) for node in ast.walk(as_json) if isinstance(node, ast.Assign)
                          and any(isinstance(t, ast.Name) and t.id == "reason" for t in node.targets)))
    assert "peer_lost" in early and "end_of_record" in creep  # the search finds them
    documented = [_code(row[0]) for row in _tables(_section())["value"]]
    assert sorted(documented) == sorted(early | creep)
