"""The XCP guide (docs/how-to/xcp.md): its script runs as a user runs it (ecu-stub's TCU and XCP slave in a thread
on python-can's virtual bus, pyxcp as the master, pya2ldb reading the A2L) and prints what the guide shows, but the
machine's count of samples; its tables name every measurement and read-only value of the memory map. Skipped without a
checkout."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from ecu_stub.xcp.memory import MEASUREMENTS, READ_ONLY

from .test_site import ROOT

PAGE = ROOT / "docs" / "how-to" / "xcp.md"
pytestmark = pytest.mark.skipif(not PAGE.exists(), reason="the docs are in the checkout only")
SAMPLES = re.compile(r"^(\d+) samples, the last at (\d+) ms: T_CL_Pred ([\d.]+) degC, margin ([-\d.]+) K, "
                     r"integrator (-?\d+) N$")


def block(language: str) -> str:
    (found,) = re.findall(rf"^```{language}\n(.*?)^```", PAGE.read_text(encoding="utf-8"), re.S | re.M)
    return found


@pytest.mark.slow
def test_the_guide_s_script_prints_what_it_shows(tmp_path: Path) -> None:
    pytest.importorskip("pyxcp")
    pytest.importorskip("pya2l")
    (tmp_path / "measure.py").write_text(block("python"), encoding="utf-8")
    proc = subprocess.run([sys.executable, "measure.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    shown = block("text").splitlines()
    printed = [line for line in proc.stdout.splitlines() if line in shown or SAMPLES.match(line)]
    assert [printed[0], printed[2]] == [shown[0], shown[2]] and len(printed) == 3, proc.stdout
    got, expected = SAMPLES.match(printed[1]), SAMPLES.match(shown[1])
    assert got and expected and int(got.group(1)) > 0 and int(got.group(2)) == 10 * (int(got.group(1)) - 1)
    if got.group(2) == expected.group(2):  # the same last sample: the same values (lock-step)
        assert got.groups()[2:] == expected.groups()[2:]


def test_the_guide_names_the_memory_map() -> None:
    page = PAGE.read_text(encoding="utf-8")
    table = page[page.index("| name | type | unit | what |"):page.index("Calibration values")]
    rows = [row.split("|")[1] for row in table.splitlines()[2:] if row.startswith("|")]
    names = {name for row in rows for name in re.findall(r"`(\w+)`", row)}
    assert names == {m.name for m in MEASUREMENTS}
    for name in READ_ONLY:
        assert f"`{name.removeprefix('clutch.CL.').removeprefix('clutch.CH.')}`" in page, name
