"""The safety argument's evidence from a sweep's table (``dsg-hil sweep dsg_hil/data/sweeps/safety.toml``, finished or
interrupted): the verdict's counts and violations, the hottest true plate and the smallest margins, the overheat
stops' hotter plate (used to >= 235 degC before giving up?), roll-back (distance, and speed against the 10-mm/s
drivability target, split by whether a frame fault was injected; those without one inside the operating range listed
with their latent sensor faults: ``bench/rerun_sweep_runs.py OUT ID --without-latent`` shows what those did), the
speed through handovers against +-20 % (all, and without the driver's pedal in the handover's window, those without
a frame fault listed), the top speed over the desired one, and FAULT outside the injected faults' windows.

    python bench/safety_findings.py OUT [--json]

Reads ``OUT/table`` only (pyarrow): the figures of a sweep still running are those of its runs so far.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from dsg_hil.results.thresholds import SAFETY_TEMPERATURE_C
from dsg_hil.sweep.page import HANDOVER_DRIVABLE_PCT, ROLLBACK_DRIVABLE_MPS

USED_C = 235.0  # the hotter clutch used to at least this before an overheat stop (used to its limit)


def findings(out: Path) -> dict:
    from dsg_hil.sweep.results import read_table  # noqa: PLC0415 - pyarrow: the sweep extra

    try:
        rows = read_table(out).to_pylist()
    except (OSError, ValueError) as exc:  # pyarrow's ArrowInvalid is a ValueError: a file that is not Parquet
        raise ValueError(f"{out}/table: not a sweep's table ({str(exc).splitlines()[0]})") from exc
    if not rows:
        raise ValueError(f"{out}/table: no rows")
    judged = [r for r in rows if r["verdict"] in ("ok", "violation", "outside_range")]  # all but the failed
    hottest = max(judged, key=lambda r: r["max_plate_temp_c"])
    stops = [r for r in judged if r["stop_reason"] == "STOPPED_OVERHEAT"]
    hotter = [(max(r["max_plate_temp_c.CL"], r["max_plate_temp_c.CH"]), r["run_id"]) for r in stops]
    fast = [r for r in judged if r["rollback_mps"] is not None and -r["rollback_mps"] > ROLLBACK_DRIVABLE_MPS]
    fast_without = [r for r in fast if not r["in.fault"]]  # faster than the target without a frame fault
    fast_in_range = sorted([r["rollback_mps"], r["run_id"], r.get("in.latent") or ""] for r in fast_without
                           if r["verdict"] != "outside_range")
    over = max(judged, key=lambda r: r["v_max_mps"] - r["v_desired_max_mps"])
    ratio = [r["v_max_mps"] / r["v_desired_max_mps"] for r in judged if r["v_desired_max_mps"]]
    predicted = [r["min_margin_c.predicted"] for r in judged if r.get("min_margin_c.predicted") is not None]
    through = [(r["handover_deviation_pct"], r["run_id"]) for r in judged
               if r.get("handover_deviation_pct") is not None]  # (a table of a sweep before the key: none)
    unbraked = [r for r in judged if (r.get("handover_deviation_unbraked_pct") or 0.0) > HANDOVER_DRIVABLE_PCT]
    return {
        "runs": len(rows), "judged": len(judged), "codes": sorted({r.get("code") for r in rows} - {None}),
        "violating": [(r["run_id"], r["violations"]) for r in rows if r["verdict"] == "violation"],
        "failed": [(r["run_id"], r["error"]) for r in rows if r["verdict"] == "error"],
        "outside_range": sum(r["verdict"] == "outside_range" for r in rows),  # judged, beyond the documented range
        "hottest_plate_c": round(hottest["max_plate_temp_c"], 2), "hottest_run": hottest["run_id"],
        f"above_{SAFETY_TEMPERATURE_C:g}_c_runs": sum(r["max_plate_temp_c"] > SAFETY_TEMPERATURE_C for r in judged),
        "min_margin_predicted_c": min(predicted) if predicted else None,
        "overheat_stops": len(stops),
        "stop_hotter_plate_min_c": min(hotter)[0] if hotter else None,
        "stop_hotter_plate_min_run": min(hotter)[1] if hotter else None,
        f"stops_below_{USED_C:g}_c": sum(t < USED_C for t, _ in hotter),
        "rollback_max_m": max(r["rollback_m"] for r in judged),
        "rollback_guarded_max_m": max(r["rollback_guarded_m"] or 0.0 for r in judged),
        f"rollback_faster_than_{ROLLBACK_DRIVABLE_MPS * 1000:g}mm_s": {
            "runs": len(fast), "with_a_frame_fault": sum(bool(r["in.fault"]) for r in fast),
            "worst_without": min((r["rollback_mps"] for r in fast_without), default=None),
            "in_range_without": fast_in_range},  # [mps, run, latent]: the roll-backs claim 2 speaks of
        "top_speed_over_desired_max_mps": round(over["v_max_mps"] - over["v_desired_max_mps"], 4),
        "top_speed_over_desired_run": over["run_id"],
        "top_speed_above_1.2x_desired_runs": sum(x > 1.2 for x in ratio),
        "handover_judged_runs": len(through),
        f"handover_beyond_{HANDOVER_DRIVABLE_PCT:g}_pct_runs": sum(d > HANDOVER_DRIVABLE_PCT for d, _ in through),
        "handover_deviation_max": max(through) if through else None,
        f"handover_beyond_{HANDOVER_DRIVABLE_PCT:g}_pct_unbraked_runs": len(unbraked),
        f"handover_beyond_{HANDOVER_DRIVABLE_PCT:g}_pct_unbraked_no_fault": sorted(
            (r["handover_deviation_unbraked_pct"], r["run_id"]) for r in unbraked if not r.get("in.fault")),
        "fault_unexplained_max_s": max(r["fault_unexplained_s"] or 0.0 for r in judged),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", type=Path, help="the sweep's --out directory")
    ap.add_argument("--json", action="store_true", help="one JSON document instead of lines")
    args = ap.parse_args(argv)
    if not (args.out / "table").is_dir():
        print(f"safety_findings: {args.out}/table: no such directory (not a sweep's --out)", file=sys.stderr)
        return 2
    try:
        result = findings(args.out)
    except (ImportError, ValueError, KeyError) as exc:  # no pyarrow; not a sweep's table; a column missing
        print(f"safety_findings: {exc if not isinstance(exc, KeyError) else f'{args.out}/table: no column {exc}'}",
              file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        for key, value in result.items():
            print(f"{key}: {value}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
