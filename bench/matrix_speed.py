"""Speed per matrix, side by side in one run: the lock-step closed loop (plant + the bundled TCU in one process, as
``dsg-hil run`` runs it) on the shipped DBC, on the ARXML example (dbc/examples/arxml/) and on the second matrix
(dbc/examples/dct_fd/); wall and CPU seconds of the loop per 10 simulated s, each against the shipped DBC's; and a
digest of every frame the plant sent and took (the same frames, bit for bit: the same digest).

    python bench/matrix_speed.py [CASE ...] [--seconds 10] [--rounds 3] [--tree DIR] [--baseline-tree DIR] [--cold]
                                 [--json]

Each case runs in fresh processes (as a user's ``dsg-hil run``), the cases alternating, ``--rounds`` times each, the
best kept (a busy machine only ever slows a run down; every round's figure is in ``rounds``). A process first runs
0.2 s of the case (the plant's compiled code loaded from numba's cache, the codec's functions generated), then
times ``Run.run()`` alone; a second run of the same case, capturing its frames, gives the digest.
``--baseline-tree DIR``: the same cases on another checkout's package (e.g. main before a change) through
PYTHONPATH, on this checkout's files: ``vs_baseline`` (this tree's time over the baseline's: below 1, faster) and
whether the frames are equal. ``--tree DIR``: the package to time instead of this checkout's (e.g. a compiled
build's: ``pip install --no-deps --target DIR .``), on this checkout's files. ``--cold``: also each case's first
run in a process with an empty numba cache (``NUMBA_CACHE_DIR``), as the first run after an install or in a new
checkout pays the plant's compilation (``cold_wall_s``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "dbc" / "examples"
CASES: dict[str, tuple[Path | None, Path | None]] = {  # case: (database, binding), files of this checkout
    "shipped": (None, None),
    "arxml": (EXAMPLES / "arxml" / "tcu.arxml", EXAMPLES / "arxml" / "tcu.binding.toml"),
    "dct_fd": (EXAMPLES / "dct_fd" / "dct_fd.dbc", EXAMPLES / "dct_fd" / "dct_fd.binding.toml"),
}
PER_S = 10.0  # figures per this many simulated seconds
NEUTRAL_CWD = tempfile.gettempdir()  # 'python -m' puts the working directory first on sys.path: not a checkout


def frames_digest(frames: Iterable[Any]) -> str:
    """SHA-256 (first 16 hex digits) of frames in order: ID, its format, the bit-rate switch, the data (not the
    timestamps, which are wall time)."""
    h = hashlib.sha256()
    for f in frames:
        h.update(f"{f.arbitration_id:x} {int(f.is_extended_id)}{int(f.is_fd)}{int(f.bitrate_switch)} "
                 f"{bytes(f.data).hex()};".encode())
    return h.hexdigest()[:16]


def one(case: str, seconds: float) -> dict:
    """The case in this process: a warm-up run, the timed run, a captured run for the digest."""
    from dsg_hil.sim.run import RunConfig, open_run

    dbc, binding = CASES[case]
    t0 = time.perf_counter()
    with open_run(RunConfig(duration=0.2, dbc=dbc, binding=binding)) as run:
        run.run()
    first = time.perf_counter() - t0
    with open_run(RunConfig(duration=seconds, dbc=dbc, binding=binding)) as run:
        t0, c0 = time.perf_counter(), time.process_time()
        summary = run.run().as_json()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    with open_run(RunConfig(duration=seconds, dbc=dbc, binding=binding, capture=True)) as run:
        run.run()
        frames = run.frames
    return {"wall_s": wall, "cpu_s": cpu, "first_run_s": first, "frames": len(frames),
            "digest": frames_digest(frames), "rejected": summary["frames"]["rejected"]}


def one_in(tree: Path | None, case: str, seconds: float, cache: str | None = None) -> dict:
    """:func:`one` in a fresh process on ``tree``'s package (None: this one's); ``cache``: its numba cache."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree if tree is not None else ROOT)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = cache
    argv = [sys.executable, str(Path(__file__).resolve()), "--one", case, "--seconds", str(seconds)]
    proc = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=NEUTRAL_CWD, timeout=120 * seconds + 300)
    if proc.returncode != 0:
        raise RuntimeError(f"{case} on {tree or ROOT}: {proc.stderr.strip()[-2000:]}")
    return json.loads(proc.stdout)


def measure(tree: Path | None, cases: list[str], seconds: float, rounds: int, cold: bool) -> dict[str, dict]:
    """Each case's best of ``rounds`` fresh processes (the cases alternating), per :data:`PER_S` simulated s."""
    runs: dict[str, list[dict]] = {case: [] for case in cases}
    for _ in range(rounds):
        for case in cases:
            runs[case].append(one_in(tree, case, seconds))
    out = {}
    for case, r in runs.items():
        best = min(r, key=lambda x: x["wall_s"])
        digests = {x["digest"] for x in r}
        out[case] = {"wall_s_per_10_s": round(best["wall_s"] * PER_S / seconds, 3),
                     "cpu_s_per_10_s": round(min(x["cpu_s"] for x in r) * PER_S / seconds, 3),
                     "rounds": [round(x["wall_s"] * PER_S / seconds, 3) for x in r],
                     "frames": best["frames"], "rejected": best["rejected"],
                     "digest": best["digest"] if len(digests) == 1 else sorted(digests)}
        if cold:
            with tempfile.TemporaryDirectory() as cache:
                out[case]["cold_wall_s"] = round(one_in(tree, case, 0.2, cache)["first_run_s"], 2)
    shipped = out.get("shipped")
    for figures in out.values():
        if shipped is not None:
            figures["vs_shipped"] = round(figures["wall_s_per_10_s"] / shipped["wall_s_per_10_s"], 2)
            figures["vs_shipped_cpu"] = round(figures["cpu_s_per_10_s"] / shipped["cpu_s_per_10_s"], 2)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", nargs="*", metavar="CASE", help=f"cases (default: all): {' '.join(CASES)}")
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds of each timed run (default 10)")
    ap.add_argument("--rounds", type=int, default=3, help="fresh processes per case, the best kept (default 3)")
    ap.add_argument("--tree", type=Path, metavar="DIR", help="the package to time (default: this checkout's)")
    ap.add_argument("--baseline-tree", type=Path, metavar="DIR", help="also run the cases on this checkout's package")
    ap.add_argument("--cold", action="store_true", help="also each case's first run with an empty numba cache")
    ap.add_argument("--json", action="store_true", help="one JSON object instead of the table")
    ap.add_argument("--one", choices=list(CASES), help=argparse.SUPPRESS)  # (a fresh process: one case, JSON)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one, args.seconds)))
        return
    if unknown := [c for c in args.cases if c not in CASES]:
        ap.error(f"unknown case(s): {' '.join(unknown)}")
    cases = args.cases or list(CASES)
    tree = args.tree.resolve() if args.tree is not None else None
    out: dict = {"seconds": args.seconds, "rounds": args.rounds,
                 "cases": [{"case": c, **f} for c, f in measure(tree, cases, args.seconds, args.rounds,
                                                                  args.cold).items()]}
    if tree is not None:
        out["tree"] = str(args.tree)
    if args.baseline_tree is not None:
        base = measure(args.baseline_tree.resolve(), cases, args.seconds, args.rounds, args.cold)
        out["baseline_tree"] = str(args.baseline_tree)
        out["baseline"] = [{"case": c, **f} for c, f in base.items()]
        for row in out["cases"]:
            other = base[row["case"]]
            row["vs_baseline"] = round(row["wall_s_per_10_s"] / other["wall_s_per_10_s"], 2)
            row["vs_baseline_cpu"] = round(row["cpu_s_per_10_s"] / other["cpu_s_per_10_s"], 2)
            row["frames_equal_baseline"] = row["digest"] == other["digest"]
    if args.json:
        print(json.dumps(out))
        return
    print(f"lock-step closed loop (plant + ecu-stub, one process), {args.seconds:g} simulated s, best of "
          f"{args.rounds} fresh processes; wall and CPU s of the loop per {PER_S:g} simulated s")
    rows = [(str(args.tree or "this tree"), out["cases"])]
    if "baseline" in out:
        rows.append((str(args.baseline_tree), out["baseline"]))
    for label, table in rows:
        print(label)
        for r in table:
            keys = ("vs_shipped", "vs_shipped_cpu", "vs_baseline", "vs_baseline_cpu", "frames_equal_baseline",
                    "cold_wall_s")
            extra = "".join(f"  {k} {r[k]}" for k in keys if k in r)
            print(f"  {r['case']:<8} wall {r['wall_s_per_10_s']:6.3f} s  CPU {r['cpu_s_per_10_s']:6.3f} s  "
                  f"frames {r['frames']}  digest {r['digest']}{extra}")


if __name__ == "__main__":
    main()
