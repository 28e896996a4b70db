"""Runs of an earlier sweep again on this tree: each run's task from ``OUT/runs/ID.json`` (the scenario, parameters,
faults and controller the sweep gave it) through the sweep's own worker (``dsg_hil.sweep.worker.run_task``), its
row then and now side by side for the keys asked. For a summary metric added after the sweep ran (e.g.
``handover_deviation_unbraked_pct``), or to see what a change of the TCU did to the runs a sweep found.
``--without-latent``: each run without its latent sensor faults (the sample's ``latent`` input), all else as
drawn: what those faults did to it; ``--latent 'F; F'``: with these instead (``--fault`` syntax), e.g. a fault's
value moved to its threshold.

    python bench/rerun_sweep_runs.py OUT [ID ...] [--beyond KEY=LIMIT] [--keys K,K,...]
                                     [--without-latent | --latent 'F; F'] [--json]

IDs: run IDs or their ``rNNNNN`` prefix (``sNNNNN``: a search's trials); ``--beyond KEY=LIMIT``: also every run
whose row then had ``KEY`` above ``LIMIT`` (e.g. ``handover_deviation_pct=20``). Reads ``OUT/runs`` and
``OUT/table``; writes nothing.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

DEFAULT_KEYS = "verdict,max_plate_temp_c,handover_deviation_pct,handover_deviation_unbraked_pct,rollback_mps"


def records(out: Path, ids: list[str], beyond: tuple[str, float] | None) -> list[dict[str, Any]]:
    """The run records of ``ids`` (whole IDs or ``rNNNNN`` / ``sNNNNN`` prefixes) and of the runs beyond ``beyond``,
    in run order; a ValueError naming what is not there."""
    files = {p.stem: p for p in (out / "runs").glob("[rs][0-9]*.json")}
    chosen: set[str] = set()
    for ident in ids:
        found = [stem for stem in files if stem == ident or stem.split("-")[0] == ident]
        if not found:
            raise ValueError(f"{out}/runs: no run {ident}")
        chosen.update(found)
    if beyond is not None:
        from dsg_hil.sweep.results import read_table  # noqa: PLC0415 - pyarrow: the sweep extra

        key, limit = beyond
        rows = read_table(out).to_pylist()
        if rows and key not in rows[0]:
            raise ValueError(f"{out}/table: no column {key}")
        chosen.update(r["run_id"] for r in rows if r.get(key) is not None and float(r[key]) > limit)
    missing = sorted(chosen - set(files))
    if missing:
        raise ValueError(f"{out}/runs: no record of {missing[0]}")
    return [json.loads(files[stem].read_text()) for stem in sorted(chosen)]


def latent_list(latent: str) -> list[str]:
    """The ``--fault`` strings of ``--latent`` (joined by ``;``, as a sample draws them; ``""``: none), each parsed
    once; a ValueError names one that is not a fault."""
    from dsg_hil.protocol.faults import FaultError, parse_fault  # noqa: PLC0415 - after the arguments are checked
    from dsg_hil.sweep.latent import latent_faults  # noqa: PLC0415

    faults = latent_faults(latent)
    for fault in faults:
        try:
            parse_fault(fault)
        except FaultError as exc:
            raise ValueError(f"--latent: {exc}") from exc
    return faults


def with_latent(task: dict[str, Any], latent: list[str]) -> dict[str, Any]:
    """``task`` with the latent sensor faults ``latent`` (:func:`latent_list`) in place of its own: its ``latent``
    input and their ``--fault`` strings replaced, the frame fault and everything else as drawn, the same run ID."""
    from dsg_hil.sweep.latent import latent_faults  # noqa: PLC0415 - after the arguments are checked

    own = set(latent_faults(task["inputs"].get("latent")))
    faults = [f for f in task["faults"] if f not in own] + latent
    return {**task, "inputs": {**task["inputs"], "latent": "; ".join(latent)}, "faults": faults}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", type=Path, help="the sweep's --out directory")
    ap.add_argument("ids", nargs="*", help="run IDs (or their rNNNNN / sNNNNN prefix)")
    ap.add_argument("--beyond", metavar="KEY=LIMIT", help="also the runs whose row had KEY above LIMIT")
    ap.add_argument("--keys", default=DEFAULT_KEYS, help=f"row keys to show, then and now (default {DEFAULT_KEYS})")
    replace = ap.add_mutually_exclusive_group()
    replace.add_argument("--without-latent", action="store_true",
                        help="run each without its latent sensor faults (the frame fault and all else as drawn)")
    replace.add_argument("--latent", metavar="'F; F'",
                        help="run each with these latent sensor faults (--fault syntax) instead of its own")
    ap.add_argument("--json", action="store_true", help="one JSON object per run instead of lines")
    args = ap.parse_args(argv)
    beyond = None
    if args.beyond is not None:
        key, _, limit = args.beyond.partition("=")
        try:
            beyond = (key, float(limit))
        except ValueError:
            print(f"rerun_sweep_runs: --beyond {args.beyond}: give KEY=LIMIT, LIMIT a number", file=sys.stderr)
            return 2
    if not (args.out / "runs").is_dir():
        print(f"rerun_sweep_runs: {args.out}/runs: no such directory (not a sweep's --out)", file=sys.stderr)
        return 2
    try:
        chosen = records(args.out, args.ids, beyond)
    except (ImportError, ValueError) as exc:
        print(f"rerun_sweep_runs: {exc}", file=sys.stderr)
        return 2
    if not chosen:
        print("rerun_sweep_runs: no run chosen: give IDs or --beyond", file=sys.stderr)
        return 2
    try:
        latent = [] if args.without_latent else None if args.latent is None else latent_list(args.latent)
    except ValueError as exc:
        print(f"rerun_sweep_runs: {exc}", file=sys.stderr)
        return 2
    from dsg_hil.sweep.worker import run_task  # noqa: PLC0415 - after the arguments are checked

    keys = [k for k in args.keys.split(",") if k]
    for rec in chosen:
        now = run_task(rec["task"] if latent is None else with_latent(rec["task"], latent))["row"]
        then = rec["row"]
        if args.json:
            print(json.dumps({"run_id": rec["run_id"], "then": {k: then.get(k) for k in keys},
                              "now": {k: now.get(k) for k in keys}}))
        else:
            print(rec["run_id"] + "  " + "  ".join(f"{k}: {then.get(k)} -> {now.get(k)}" for k in keys), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
