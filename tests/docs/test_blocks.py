"""The code and shell blocks of README.md and docs/ hold: every dsg-hil, ecu-stub and identification command line
in them is accepted by the parser the command runs (nothing run), the quick start's run prints what the README
shows (but the machine's pace), and the quick guides' commands run. The python blocks of the tutorials and the FMI
guide are run by the tests beside the code they show (tests/sim/test_run.py, tests/testing/test_example.py,
tests/fmi/test_readme.py); the site's build is tests/docs/test_site.py. Skipped without a checkout."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(not (ROOT / "mkdocs.yml").exists(), reason="the docs are in the checkout only")
PAGES = [ROOT / "README.md", *sorted(p for p in (ROOT / "docs").rglob("*.md"))]
BIN = Path(sys.executable).parent


def blocks(language: str) -> list[tuple[Path, str]]:
    """Every fenced block of that language in README.md and docs/, with its page."""
    found = []
    for page in PAGES:
        for block in re.findall(rf"^```{language}\n(.*?)^```", page.read_text(encoding="utf-8"), re.S | re.M):
            found.append((page, block))
    return found


def page_blocks(language: str, page: Path) -> list[str]:
    """The fenced blocks of that language of one page."""
    return [block for where, block in blocks(language) if where == page]


def command_lines() -> list[tuple[str, list[str]]]:
    """The dsg-hil, ecu-stub and identification commands of every sh block (a '$ ' prompt, comments, '&&',
    'source <(...)' and a '> FILE' redirection taken apart), with where they are."""
    found = []
    for page, block in blocks("sh"):
        for line in block.splitlines():
            line = line.removeprefix("$ ").replace("source <(", "").replace(")", " ") if "<(" in line else \
                line.removeprefix("$ ")
            for part in re.split(r"&&|\|", line):
                words = shlex.split(part.split(" > ")[0], comments=True)  # a redirection is the shell's
                if words[:1] in (["dsg-hil"], ["ecu-stub"]) or words[:3] == ["python", "-m", "ecu_stub.identify"]:
                    found.append((f"{page.relative_to(ROOT)}: {part.strip()}", words))
    return found


def _accepts(words: list[str]) -> None:
    """Parse a command line with the parser its command runs (argparse exits 2 on what it refuses)."""
    if words[0] == "dsg-hil":
        from dsg_hil.cli import _parse_args
        _parse_args(words[1:])
    elif words[0] == "ecu-stub":
        from ecu_stub.cli import _parse_args as ecu_parse
        ecu_parse(words[1:])
    else:
        from ecu_stub.identify import _parse_args as identify_parse
        identify_parse(words[3:])


LINES = command_lines()


def test_there_are_command_lines_to_check():
    pages = {where.split(":")[0] for where, _ in LINES}
    assert len(LINES) >= 20 and {"README.md", "docs/how-to/faults.md", "docs/tutorials/sweep.md"} <= pages


@pytest.mark.parametrize("words", [w for _, w in LINES], ids=[where for where, _ in LINES])
def test_every_documented_command_line_parses(words):
    _accepts(words)


def _run(*argv: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}
    return subprocess.run(list(argv), cwd=cwd, capture_output=True, text=True, timeout=600, env=env)


PACE = re.compile(r"\s+[\d.]+x real time, ETA \d+ s$|in [\d.]+ s wall")  # the machine's, not the run's
NUMBER = re.compile(r"-?\d+(?:\.\d+)?")


def same_line(shown: str, printed: str) -> bool:
    """The README's line and the run's agree: the same words, and each number within one unit of its last printed
    digit (-0.00 is 0.00, the columns aside). Lockstep gives the same frames bit for bit on one machine; between
    CPUs the last bits of a float differ (numba compiles the physics for the host's CPU, with or without fused
    multiply-add), and printed to 0.1 degC a temperature may round the other way."""
    if re.sub(r"\s", "", NUMBER.sub("#", shown)) != re.sub(r"\s", "", NUMBER.sub("#", printed)):  # a sign's column
        return False
    pairs = zip(NUMBER.findall(shown), NUMBER.findall(printed))
    return all(abs(float(a) - float(b)) <= 1.01 * 10.0 ** -len(a.partition(".")[2]) for a, b in pairs)


def test_same_line_tells_a_rounding_from_a_change():
    line = "t=  160.0/240 s  v= 0.21 m/s  T_CL= 244.2  T_CH= 239.5 degC  TCU CREEP/CH"
    assert same_line(line, line.replace("244.2", "244.1")) and same_line(line, line.replace("0.21", "0.20"))
    assert same_line("v= 0.00 m/s", "v=-0.00 m/s")
    assert not same_line(line, line.replace("244.2", "244.0")) and not same_line(line, line.replace("CH", "CL"))
    assert not same_line(line, line.replace("160.0", "160.2")) and not same_line(line, line + " more")


# the three numbers the README compares with the paper: within what a CPU's rounding moves them (a temperature
# 0.05 K, the stop's time one 10-ms control period), far below their distance from the paper's
SUMMARY_TOLERANCE = {"tcu_stop_time_s": 0.01, "T_CL_at_first_CH_limit_c": 0.05, "T_CL_at_stop_c": 0.05}


@pytest.mark.slow
def test_the_quick_start_run_prints_what_the_readme_shows(tmp_path):
    """'dsg-hil run' as the quick start runs it, with the output files of the first tutorial's command (which the
    logs guide's is a part of): the README's lines, but the pace, are the run's (lockstep: the same lines but for a
    CPU's rounding, see same_line), and its table's three numbers are the summary's; the log is written."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    quick = readme.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    assert re.search(r"```sh\n.*&& dsg-hil run\n", quick)
    shown = re.search(r"```text\n(.*?)```", quick, re.S)
    assert shown
    (tutorial,) = page_blocks("sh", ROOT / "docs" / "tutorials" / "first-creep.md")
    (logs,) = page_blocks("sh", ROOT / "docs" / "how-to" / "logs.md")
    words = shlex.split(tutorial)
    assert words == ["dsg-hil", "run", "--log", "run.log", "--summary", "summary.json"]
    assert shlex.split(logs) == words[:4]  # a part of it
    done = _run(str(BIN / "dsg-hil"), *words[1:], cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "run.log").stat().st_size > 0
    printed = [PACE.sub("", line) for line in (done.stdout + done.stderr).splitlines()]
    for line in shown.group(1).splitlines():
        if line != "...":
            line = PACE.sub("", line)
            assert any(same_line(line, other) for other in printed), (line, printed)
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    numbers = re.findall(r"^\| `(\w+)`: [^|]*\| ([\d.]+) ", quick, re.M)
    assert [key for key, _ in numbers] == list(SUMMARY_TOLERANCE)  # the three to compare with the paper
    for key, value in numbers:
        assert summary[key] == pytest.approx(float(value), abs=SUMMARY_TOLERANCE[key]), key
    assert summary["stop_reason"] == "STOPPED_OVERHEAT"


def test_the_parameters_guide_runs(tmp_path):
    listed = _run(str(BIN / "dsg-hil"), "params", "--source", "calibrated", cwd=tmp_path)
    rows = [line.split() for line in listed.stdout.splitlines() if line and not line.startswith("#")]
    assert listed.returncode == 0 and rows and all(row[3] == "calibrated" for row in rows)
    changed = _run(str(BIN / "dsg-hil"), "params", "--set", "vehicle.m=9000", cwd=tmp_path)
    row = next(line.split() for line in changed.stdout.splitlines() if line.startswith("vehicle.m "))
    assert changed.returncode == 0 and row[1:4] == ["9000", "kg", "override"] and "(was 7840" in " ".join(row)


@pytest.mark.slow
def test_the_fault_guide_s_python_block_gives_the_counts_it_shows(tmp_path):
    """The block's last line shows the summary's fault counts in a comment: the run gives those."""
    (_, block), = [(p, b) for p, b in blocks("python") if p.name == "faults.md"]
    shown = re.search(r'"injected": \{"([^"]+)": (\d+)\}', block)
    assert shown
    done = _run(sys.executable, "-c", block + "\nprint(__import__('json').dumps(result.summary['faults']))",
                cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    faults = json.loads(done.stdout.strip().splitlines()[-1])
    assert faults["seed"] == 0 and faults["injected"] == {shown.group(1): int(shown.group(2))}


def test_every_toml_block_of_fault_tables_is_a_fault_the_dbc_takes():
    """A ``[[fault]]`` table shown in the docs is read as a scenario's are, and checked against the shipped DBC."""
    import tomllib

    from dsg_hil.protocol.codec import load_dbc
    from dsg_hil.protocol.faults.spec import check_faults, fault_from_mapping

    tables = [table for _, block in blocks("toml") for table in tomllib.loads(block).get("fault", [])]
    assert tables
    by_side = check_faults([fault_from_mapping(table) for table in tables], load_dbc())
    assert sum(map(len, by_side.values())) == len(tables)
