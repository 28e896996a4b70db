"""Sweep throughput on Dask, side by side in one run: the default creep (the shipped scenario,
240 simulated s, the bundled ecu-stub) as ``dsg-hil sweep`` runs it, on a LocalCluster of 1 worker and of 2 workers
(one thread each), alternating, ``--rounds`` times; per configuration the runs per minute, the scaling efficiency
(rate with N workers / (N x the rate with 1)), runs per core-hour and each worker's memory: its peak resident set, and
its private memory after its runs (:func:`private_mb`).

    python bench/sweep_scaling.py [--runs-per-worker 4] [--duration 240] [--rounds 2] [--workers 1 2] [--json]

Each configuration gets ``--runs-per-worker`` x N runs, so that every worker has the same work; the clock runs from
the first submission to the last result (the cluster's start-up, paid once per sweep, is reported apart:
``startup_s``). The workers warm up as a sweep's do (the numba cache prepared before they start). On a 2-core
machine 2 workers use every core: whatever else runs there (this bench's own process only waits) shows as
efficiency lost, so run it on an idle machine and read the rounds (every round's figure is kept; the best counts,
since other load only ever slows a round down). Needs pip install 'dsg-hil[sweep]'.
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time
from pathlib import Path
from typing import Any

from dsg_hil.sweep.engine import open_client, result_of, submit
from dsg_hil.sweep.space import load_space

SPACE = """
name = "default-creep"
seed = 1
n = {n}
duration_s = {duration}
[inputs]
"initial.v_mps" = {{fixed = 0.0}}
"""


def peak_rss_mb() -> float:
    """The calling process's peak resident set [MB] (run on each worker)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def private_mb() -> float:
    """The calling process's private dirty memory now [MB] (run on each worker after its runs): what it wrote
    (heap, arrays, compiled code), without the pages of shared libraries mapped from disk. Those count in the
    resident set as far as the page cache holds them, which the process does not decide: the same 178-MB llvmlite
    library, byte for byte, was 36 MB of a run's resident set in one virtual environment and 96 MB in a fresh
    one."""
    with open("/proc/self/smaps_rollup", encoding="ascii") as f:
        for line in f:
            if line.startswith("Private_Dirty:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def one_sweep(workers: int, runs: int, duration: float, tmp: Path) -> dict[str, Any]:
    """``runs`` runs of the default creep on a LocalCluster of ``workers``: runs per minute, start-up, peak RSS."""
    path = tmp / f"space-{workers}-{runs}.toml"
    path.write_text(SPACE.format(n=runs, duration=duration), encoding="utf-8")
    tasks = load_space(path).tasks(runs)
    t0 = time.monotonic()
    with open_client(workers) as (client, _):
        t1 = time.monotonic()
        futures = submit(client, tasks, keep_logs=False)
        rows = [result_of(f, t)["row"] for f, t in zip(futures, tasks)]
        wall = time.monotonic() - t1
        rss, private = client.run(peak_rss_mb), client.run(private_mb)
    failed = [r["run_id"] for r in rows if r.get("verdict") == "error"]
    if failed:
        raise RuntimeError(f"runs failed: {failed}")
    return {"workers": workers, "runs": runs, "wall_s": round(wall, 2), "startup_s": round(t1 - t0, 2),
            "runs_per_min": round(60.0 * runs / wall, 2),
            "worker_peak_rss_mb": sorted(round(v, 1) for v in rss.values()),
            "worker_private_mb": sorted(round(v, 1) for v in private.values())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs-per-worker", type=int, default=4, help="runs per worker and configuration (default 4)")
    ap.add_argument("--duration", type=float, default=240.0, help="simulated s per run (default 240: the default "
                    "creep)")
    ap.add_argument("--rounds", type=int, default=2, help="rounds of every configuration, alternating (default 2)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="worker counts (default 1 2)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    rounds: dict[int, list[dict[str, Any]]] = {n: [] for n in args.workers}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.rounds):
            for n in args.workers:
                rounds[n].append(one_sweep(n, args.runs_per_worker * n, args.duration, Path(tmp)))
                if not args.json:
                    r = rounds[n][-1]
                    print(f"  {n} worker(s): {r['runs']} runs in {r['wall_s']} s, {r['runs_per_min']} runs/min, "
                          f"peak RSS per worker {r['worker_peak_rss_mb']} MB, private {r['worker_private_mb']} MB",
                          flush=True)
    best = {n: max(rs, key=lambda r: r["runs_per_min"]) for n, rs in rounds.items()}
    base = min(args.workers)
    single = best[base]["runs_per_min"] / base
    out = {"duration_s": args.duration, "runs_per_worker": args.runs_per_worker,
           "configurations": {str(n): {**best[n], "rounds_runs_per_min": [r["runs_per_min"] for r in rounds[n]],
                                       "efficiency": round(best[n]["runs_per_min"] / (n * single), 3)}
                              for n in args.workers},
           "runs_per_core_hour": round(60.0 * single),
           "x_real_time_per_worker": round(single * args.duration / 60.0, 1),
           "worker_peak_rss_mb_max": max(max(r["worker_peak_rss_mb"]) for rs in rounds.values() for r in rs),
           "worker_private_mb_max": max(max(r["worker_private_mb"]) for rs in rounds.values() for r in rs)}
    if args.json:
        print(json.dumps(out))
        return
    for n in args.workers:
        c = out["configurations"][str(n)]
        print(f"{n} worker(s): best {c['runs_per_min']} runs/min (rounds {c['rounds_runs_per_min']}), efficiency "
              f"{c['efficiency']:.3f} (target >= 0.9)")
    print(f"runs of the {args.duration:g}-s creep per core-hour: {out['runs_per_core_hour']} (target >= 3000); "
          f"{out['x_real_time_per_worker']}x real time per worker; largest worker peak RSS "
          f"{out['worker_peak_rss_mb_max']} MB (target <= 250), largest private {out['worker_private_mb_max']} MB")


if __name__ == "__main__":
    main()
