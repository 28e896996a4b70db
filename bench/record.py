"""Keep a benchmark's figures for the performance page: runs a bench script with ``--json``, and writes its JSON to
``bench/results/NAME.json`` with the date, the machine and the command (the page, docs/performance.md, shows every
file there).

    python bench/record.py NAME [--note TEXT] -- python bench/SCRIPT.py --json [OPTIONS]

The script's output is one JSON object, or one JSON object a line (then the results are their list). The machine is
described from this host (CPU model, cores, OS, Python); ``--note`` adds what the host cannot tell (e.g. other work
running beside it).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import shlex
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

__all__ = ["machine", "main", "parse_output"]

HERE = Path(__file__).resolve().parent


def machine(note: str = "") -> str:
    """This host in one line: cores, CPU model, OS, Python (and the note)."""
    model = platform.processor() or platform.machine()
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text(encoding="utf-8")
        model = next(line.split(":", 1)[1].strip() for line in cpuinfo.splitlines() if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    text = (f"{os.cpu_count()}-core {platform.machine()} {platform.system()}, {model}; "
            f"Python {platform.python_version()}")
    return f"{text}; {note}" if note else text


def parse_output(stdout: str) -> Any:
    """A script's ``--json`` output: one object, or one object a line (a list of them)."""
    text = stdout.strip()
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return [json.loads(line) for line in text.splitlines() if line.strip()]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("name", help="the result's name: bench/results/NAME.json")
    ap.add_argument("--note", default="", help="what else ran on the machine, or anything the host cannot tell")
    ap.add_argument("--out", type=Path, default=HERE / "results", metavar="DIR",
                    help="where NAME.json goes (default: bench/results, what the performance page shows)")
    argv = sys.argv[1:] if argv is None else argv
    if "--" not in argv or argv.index("--") == len(argv) - 1:
        ap.error("give the bench command after --")
    args = ap.parse_args(argv[:argv.index("--")])
    command = argv[argv.index("--") + 1:]
    started = time.monotonic()
    argv_run = [sys.executable if command[0] == "python" else command[0], *command[1:]]
    proc = subprocess.run(argv_run, cwd=HERE.parent, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stderr[-4000:])
        print(f"error: {shlex.join(command)} exited {proc.returncode}", file=sys.stderr)
        return 1
    record = {"date": dt.datetime.now(dt.UTC).strftime("%Y-%m-%d"), "machine": machine(args.note),
              "command": shlex.join(command), "wall_s": round(time.monotonic() - started, 1),
              "results": parse_output(proc.stdout)}
    out = args.out / f"{args.name}.json"
    out.write_text(json.dumps(record, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    print(f"{out}: {record['wall_s']} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
