"""The command line the case-by-case benchmarks share: cases by name (default: all) and ``--json``."""

from __future__ import annotations

import argparse
from collections.abc import Iterable

__all__ = ["parse_cases"]


def parse_cases(doc: str, cases: Iterable[str]) -> tuple[list[str], bool]:
    """The cases asked for (all when none is named; an unknown one: exit 2 naming it) and whether ``--json``."""
    known = list(cases)
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("cases", nargs="*", metavar="CASE", help=f"cases (default: all): {' '.join(known)}")
    ap.add_argument("--json", action="store_true", help="one JSON object instead of a line per case")
    args = ap.parse_args()
    if unknown := [c for c in args.cases if c not in known]:
        ap.error(f"unknown case(s): {' '.join(unknown)}")
    return args.cases or known, args.json
