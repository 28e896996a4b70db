"""Latent sensor faults in the shipped safety space: ``N`` runs of ``dsg_hil/data/sweeps/safety.toml`` (its
``[latent]`` section draws 0-2 offsets or gains per run on the TCU's inputs, 0.1-2.5 times each one's detection
threshold, :mod:`dsg_hil.sweep.latent`), judged on the plant's truth; prints the violations split by the runs'
latent faults (beyond a threshold, all within, none), the hottest true plate of each group, and for every run above
the plate limit its latent faults (each with its multiple of the threshold) and frame fault. ``--without-latent``
runs each of those again in this process with the same inputs but no latent fault (its frame fault kept): the
plate it then reaches says whether the latent fault made the violation.

    python bench/latent_findings.py [--n 300] [--workers 1] [--seed 1] [--out DIR [--resume]] [--without-latent]
                                    [--json FILE]

A thin call of :func:`dsg_hil.sweep.run_sweep` (pip install 'dsg-hil[sweep]'); the same runs as
``dsg-hil sweep dsg_hil/data/sweeps/safety.toml --n N --workers 1`` (a Latin hypercube: the same N draws the same
runs).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
from collections.abc import Mapping, Sequence
from typing import Any

from dsg_hil.sweep import load_space, run_sweep
from dsg_hil.sweep.latent import latent_faults, multiple, thresholds
from dsg_hil.sweep.results import ResultStore
from dsg_hil.sweep.space import SAFETY_SPACE, SpaceError
from dsg_hil.sweep.verdict import LATENT_CLASSES, latent_class
from dsg_hil.sweep.worker import run_task, runs_quiet

__all__ = ["findings", "main"]


def _hottest(rows: Sequence[Mapping[str, Any]]) -> float | None:
    return max((float(r["max_plate_temp_c"]) for r in rows if r.get("max_plate_temp_c") is not None), default=None)


def findings(rows: Sequence[Mapping[str, Any]], limit_c: float) -> dict[str, Any]:
    """What the runs show: per latent class the runs, the violating ones and the hottest plate; every run above
    ``limit_c`` with its faults."""
    limits = thresholds()
    groups: dict[str, Any] = {}
    for key in LATENT_CLASSES:
        mine = [r for r in rows if latent_class(r) == key]
        groups[key] = {"runs": len(mine), "violating": sum(r.get("verdict") == "violation" for r in mine),
                       "above_limit": sum((r.get("max_plate_temp_c") or 0.0) > limit_c for r in mine),
                       "hottest_c": _hottest(mine)}
    hot = []
    for r in sorted(rows, key=lambda r: -(r.get("max_plate_temp_c") or 0.0)):
        if (r.get("max_plate_temp_c") or 0.0) <= limit_c and r.get("verdict") != "violation":
            continue
        hot.append({"run_id": r["run_id"], "max_plate_temp_c": r.get("max_plate_temp_c"),
                    "violations": r.get("violations"), "latent_x": r.get("latent_x"),
                    "latent": [(f, round(multiple(f, limits), 3)) for f in latent_faults(r.get("in.latent"))],
                    "fault": r.get("in.fault") or "", "behaviour": r.get("in.driver.behaviour")})
    return {"runs": len(rows), "violating": sum(r.get("verdict") == "violation" for r in rows),
            "failed": sum(r.get("verdict") == "error" for r in rows), "hottest_c": _hottest(rows), "groups": groups,
            "violating_or_hot": hot}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=300, help="runs (default 300)")
    ap.add_argument("--workers", type=int, default=1, help="Dask workers (default 1: the machine may be shared)")
    ap.add_argument("--seed", type=int, help="the space's seed (default: the file's)")
    ap.add_argument("--out", metavar="DIR", help="results directory (default: a temporary one)")
    ap.add_argument("--resume", action="store_true", help="only the runs not yet in --out (all there: none run)")
    ap.add_argument("--without-latent", action="store_true",
                    help="run each violating or hot run again without its latent faults")
    ap.add_argument("--json", metavar="FILE", help="also write the findings as JSON")
    args = ap.parse_args(argv)
    space = load_space(SAFETY_SPACE)
    if args.seed is not None:
        space = dataclasses.replace(space, seed=args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            result = run_sweep(space, args.out or tmp, n=args.n, workers=args.workers, resume=args.resume,
                               progress=print)
        except SpaceError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        store = ResultStore(args.out or tmp, resume=True)
        tasks = {r["run_id"]: store.record(r["run_id"])["task"] for r in result.rows if r.get("verdict") == "violation"
                 or (r.get("max_plate_temp_c") or 0.0) > space.limits["plate_temp_c"]}
    limit = space.limits["plate_temp_c"]
    found = findings(result.rows, limit)
    print(f"\n{found['runs']} runs of {space.origin} (seed {space.seed}) in {result.wall_s:.0f} s wall, "
          f"{args.workers} worker(s): {found['violating']} violating, {found['failed']} failed; hottest true plate "
          f"{found['hottest_c']} degC")
    for key, group in found["groups"].items():
        print(f"  {group['runs']:4d} runs {LATENT_CLASSES[key]}: {group['violating']} violating, "
              f"{group['above_limit']} above {limit:g} degC, hottest {group['hottest_c']} degC")
    for hot in found["violating_or_hot"]:
        latent = "; ".join(f"{f} (x{x:g})" for f, x in hot["latent"]) or "no latent fault"
        print(f"{hot['run_id']} {hot['max_plate_temp_c']} degC {hot['violations'] or '-'} [{hot['behaviour']}] "
              f"{latent}" + (f" + frame fault {hot['fault']}" if hot["fault"] else ""))
        if args.without_latent and hot["latent"]:
            task = tasks[hot["run_id"]]
            with runs_quiet():
                again = run_task(space.task(task["index"], {k: v for k, v in task["inputs"].items()
                                                            if k != "latent"}))
            hot["without_latent"] = {"max_plate_temp_c": again["row"].get("max_plate_temp_c"),
                                     "violations": again["row"].get("violations")}
            print(f"    without its latent faults: {hot['without_latent']['max_plate_temp_c']} degC "
                  f"{hot['without_latent']['violations'] or 'no violation'}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(found, fh, indent=1, default=str)
    return 0


if __name__ == "__main__":
    sys.exit(main())
