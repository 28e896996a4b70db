"""Safety sweep: ``dsg-hil sweep`` over the shipped space (``dsg_hil/data/sweeps/safety.toml``: the documented
operating range and the driver behaviours), judged on the plant's TRUE plate temperature; prints one line per run
and the violations. A thin call of :func:`dsg_hil.sweep.run_sweep` (pip install 'dsg-hil[sweep]').

    python bench/safety_sweep.py [--n 40] [--seed 1] [--duration 240] [--jobs 2] [--out DIR] [--json FILE]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile

from dsg_hil.sweep import load_space, run_sweep
from dsg_hil.sweep.space import SAFETY_SPACE, SpaceError


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=40, help="runs (default 40)")
    ap.add_argument("--seed", type=int, default=1, help="sampler seed (default 1)")
    ap.add_argument("--duration", type=float, metavar="S", help="simulated s each (default: the space's)")
    ap.add_argument("--jobs", type=int, help="worker processes (default: one per core)")
    ap.add_argument("--out", metavar="DIR", help="results directory (default: a temporary one)")
    ap.add_argument("--json", metavar="FILE", help="also write every row as JSON")
    args = ap.parse_args(argv)
    space = load_space(SAFETY_SPACE)
    base = dict(space.base)
    if args.duration is not None:
        base["duration_s"] = args.duration
    space = dataclasses.replace(space, seed=args.seed, base=base)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            result = run_sweep(space, args.out or tmp, n=args.n, workers=args.jobs, progress=print)
        except SpaceError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    for row in result.rows:
        print(f"{row['run_id']} {row.get('in.driver.behaviour', '-'):>16} max plate {row.get('max_plate_temp_c')} "
              f"degC  stop {row.get('stop_reason')}  {row['verdict']} {row['violations']}")
    hottest = max((r["max_plate_temp_c"] for r in result.rows if r.get("max_plate_temp_c") is not None),
                  default=None)
    print(f"\n{len(result.rows)} runs in {result.wall_s:.0f} s wall; hottest plate (truth) {hottest} degC; "
          f"violations: {len(result.violations)}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump({"violations": len(result.violations), "rows": result.rows}, fh, indent=1, default=str)
    return 1 if result.violations else 0


if __name__ == "__main__":
    sys.exit(main())
