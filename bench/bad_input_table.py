"""The bad-input cases of ``tests/cli/test_bad_input.py`` (its ``CASES``, imported) run against one or more source
trees, as a markdown table: per case the command line, and per tree the exit code, the last stderr line, whether
a traceback was printed, what was created, and whether the case behaves as promised (exit 2, one ``error:`` line,
the last, naming what the case names, no traceback, nothing created: the test's own criteria).

Each tree's code runs through ``PYTHONPATH`` (this interpreter's packages otherwise), in a fresh directory per case
holding the test's input files. Usage::

    python bench/bad_input_table.py                                  # this tree
    python bench/bad_input_table.py --tree before=/work/wt-before --tree after=.   # side by side
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(HERE))

from tests.cli.test_bad_input import CASES, ERROR, PROGRAMS, write_inputs  # noqa: E402 - this tree's case list

__all__ = ["Outcome", "main", "run_case", "table"]

TIMEOUT_S = 120.0  # bad input fails at once: a case still running then was accepted (it is stopped, not promised)


@dataclass(frozen=True)
class Outcome:
    """How one case ended on one tree."""

    status: int | None  # None: timed out
    last_line: str
    traceback: bool
    created: tuple[str, ...]
    promised: bool


def run_case(tree: Path, index: int) -> Outcome:
    """Case ``index`` of CASES with the code of ``tree``, in a directory of its own."""
    program, argv, _, form, needle = CASES[index]
    with tempfile.TemporaryDirectory(prefix="bad-input-") as where:
        cwd = Path(where)
        write_inputs(cwd)
        before = set(cwd.rglob("*"))
        env = {**os.environ, "PYTHONPATH": str(tree)}
        try:
            proc = subprocess.run([sys.executable, *PROGRAMS[program], *argv], cwd=cwd, env=env,
                                  capture_output=True, text=True, timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc = None
        created = tuple(sorted(str(p.relative_to(cwd)) for p in set(cwd.rglob("*")) - before))
    if proc is None:
        return Outcome(None, f"(accepted: still running after {TIMEOUT_S:g} s, stopped)", False, created, False)
    err = proc.stderr.strip().splitlines()
    last = err[-1] if err else ""
    traceback = "Traceback" in proc.stderr
    errors = [line for line in err if "error:" in line]
    if form == ERROR:
        said = len(err) == 1 and last.startswith("error: ") and needle in last
    else:
        said = bool(err) and err[0].startswith("usage: ") and f": error: {needle}" in last
    promised = (proc.returncode == 2 and proc.stdout == "" and not traceback and errors == err[-1:] and said
                and not created)
    return Outcome(proc.returncode, last, traceback, created, promised)


def _cell(text: str, width: int = 90) -> str:
    text = text.replace("|", "\\|").replace("`", "'")
    return text if len(text) <= width else text[:width - 3] + "..."


def table(trees: dict[str, Path], jobs: int = 2) -> tuple[str, dict[str, int]]:
    """The markdown table of every case on every tree, and per tree the number of cases as promised."""
    with ThreadPoolExecutor(jobs) as pool:
        outcomes = {name: list(pool.map(lambda i, t=tree: run_case(t, i), range(len(CASES))))
                    for name, tree in trees.items()}
    head = ["#", "case"] + [f"{name}: {col}" for name in trees for col in ("exit", "stderr (last line)", "tb",
                                                                           "created", "ok")]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for i, (program, argv, *_) in enumerate(CASES):
        row = [str(i + 1), f"`{_cell(' '.join([program, *argv]), 100)}`"]
        for name in trees:
            o = outcomes[name][i]
            row += ["-" if o.status is None else str(o.status), _cell(o.last_line), "yes" if o.traceback
                    else "", _cell(", ".join(o.created), 40), "yes" if o.promised else "**no**"]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines), {name: sum(o.promised for o in outs) for name, outs in outcomes.items()}


def _tree(text: str) -> tuple[str, Path]:
    name, _, path = text.rpartition("=")
    resolved = Path(path).resolve()
    if not (resolved / "dsg_hil" / "__init__.py").is_file():
        raise argparse.ArgumentTypeError(f"{path}: not a dsg-hil source tree (no dsg_hil/__init__.py)")
    return name or resolved.name, resolved


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", type=_tree, action="append", metavar="[NAME=]DIR",
                        help="a source tree to run the cases with (repeatable; default: this one)")
    parser.add_argument("--jobs", type=int, default=2, help="cases run at once (default 2)")
    args = parser.parse_args(argv)
    trees = dict(args.tree or [("this tree", HERE)])
    text, promised = table(trees, args.jobs)
    print(text)
    print()
    print(f"{len(CASES)} cases; as promised: " + ", ".join(f"{name} {n}" for name, n in promised.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
