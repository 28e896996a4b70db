"""The diagnostics guide (docs/how-to/diagnostics.md): its pytest example passes as a user runs it (the block
itself, in a pytest of its own), and the tables the site's hook puts in it hold every DID field and DTC of the
description ecu-stub serves. Skipped without a checkout."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ..testing.test_example import run_pytest
from .test_site import ROOT, hook

PAGE = ROOT / "docs" / "how-to" / "diagnostics.md"
pytestmark = pytest.mark.skipif(not PAGE.exists(), reason="the docs are in the checkout only")


def example() -> str:
    (block,) = [b for b in re.findall(r"^```python\n(.*?)^```", PAGE.read_text(encoding="utf-8"), re.S | re.M)
                if "def test_" in b]
    return block


@pytest.mark.slow
def test_the_guide_s_pytest_example_passes(tmp_path: Path) -> None:
    pytest.importorskip("udsoncan")
    (tmp_path / "test_my_dtc.py").write_text(example(), encoding="utf-8")
    proc = run_pytest(tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout


def _rows(table: str) -> list[list[str]]:
    return [[c.strip().strip("`") for c in line.strip("|").split("|")] for line in table.splitlines()[2:]]


def test_the_tables_hold_the_description_ecu_stub_serves() -> None:
    from dsg_hil.protocol.diag import load_description

    description = load_description()
    page = PAGE.read_text(encoding="utf-8")
    reference = hook()
    assert all(marker in page for marker in ("<!-- diag-dids -->", "<!-- diag-dtcs -->", "<!-- diag-snapshot -->"))
    fields = [(row[0], row[2]) for row in _rows(reference.did_table())]
    assert fields == [(f"0x{did.id:04X}", name) for did in description.dids.values()
                      for name in ([f.name for f in did.fields] or ["-"])]
    dtcs = _rows(reference.dtc_table())
    assert len(dtcs) == len(description.dtcs) == 23
    assert [(r[0], r[3], int(r[4])) for r in dtcs] == [(d.code, d.monitor, d.debounce) for d in description.dtcs]
    markdown = reference.on_page_markdown(page, None, None, None)
    assert "<!--" not in markdown and "0x0113 `time`" in markdown and "| `P1701` | 0x170100 |" in markdown
