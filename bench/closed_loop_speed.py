"""Closed-loop speed, side by side in one run: the lock-step closed loop (plant + ecu-stub TCU) in one process as
it runs now (generated codec, direct in-process bus) and as it ran before (cantools codec, python-can ``virtual``);
where a control period goes (the plant's physics against everything around it); the plant alone; plant and TCU as
two processes on udp_multicast; the start-up of every command; peak memory.

    python bench/closed_loop_speed.py [--seconds 60] [--udp-seconds 20] [--json] [--baseline-tree DIR] [--rounds 3]

``--baseline-tree``: also time the one-process closed loop, the two-process run and the start-ups with the package
of another checkout (e.g. the main one before these changes), through PYTHONPATH. The one-process loops of both
trees run as fresh processes, alternating, ``--rounds`` times each, the best of each kept (a busy machine only
ever slows a run down); ``closed_loop_vs_baseline_tree`` compares them in simulated seconds per CPU second of the
process (less disturbed by other load than wall time), ``..._wall`` in wall time. Figures are simulated seconds
per wall second unless named per CPU second.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dsg_hil.loop import run_closed_loop
from dsg_hil.physics.params import load_params
from dsg_hil.plant import Plant, PlantInputs
from dsg_hil.scenario import load_scenario

COMMANDS = ("run", "plant", "bridge", "dbc", "vcan", "validate", "calibrate", "params", "report")
STARTUP_REPEATS = 3


def closed_loop(seconds: float, transport: str, reference: bool) -> dict:
    """One in-process lock-step run: sim s per wall s (and per CPU s of this process, less disturbed by other
    load on the machine), and the time inside the plant's advance (a control period's steps in one call)
    against the rest of each period."""
    scenario = load_scenario().with_duration(seconds)
    inside = [0.0, 0.0]  # wall, CPU
    advance = Plant.advance

    def timed_advance(plant: Plant, inputs: PlantInputs, n_steps: int, trace=None):
        t0, c0 = time.perf_counter(), time.process_time()
        out = advance(plant, inputs, n_steps, trace)
        inside[0] += time.perf_counter() - t0
        inside[1] += time.process_time() - c0
        return out

    Plant.advance = timed_advance  # type: ignore[assignment]
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        result = run_closed_loop(scenario, transport=transport, reference_codec=reference)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        Plant.advance = advance
    periods, run = result.runner.n_periods, result.summary["wall_time_s"]  # run: the periods, without set-up
    return {"sim_s_per_wall_s": round(seconds / wall, 2), "sim_s_per_cpu_s": round(seconds / cpu, 2),
            "wall_s": round(wall, 3), "setup_s": round(wall - run, 3),
            "period_us": round(1e6 * run / periods, 1), "physics_us_per_period": round(1e6 * inside[0] / periods, 1),
            "rest_us_per_period": round(1e6 * (run - inside[0]) / periods, 1),
            "rest_cpu_us_per_period": round(1e6 * (cpu - inside[1]) / periods, 1),
            "frames_sent": result.summary["frames"]["sent"]}


def closed_loop_in(tree: str | None, seconds: float) -> dict:
    """:func:`closed_loop` (the in-process bus, generated codec) in a fresh process on ``tree``'s package."""
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--closed-loop-only", "--seconds",
                           str(seconds)], capture_output=True, text=True, check=True, env=env_for(tree),
                          cwd=NEUTRAL_CWD, timeout=60 * seconds + 120)
    return json.loads(proc.stdout)


def side_by_side(tree: str, seconds: float, rounds: int) -> dict:
    """The one-process closed loop on this package and on ``tree``'s, alternating; the best run of each."""
    best: dict[str, dict] = {}
    for _ in range(rounds):
        for key, which in (("this", None), ("baseline", tree)):
            run = closed_loop_in(which, seconds)
            if key not in best or run["sim_s_per_cpu_s"] > best[key]["sim_s_per_cpu_s"]:
                best[key] = run
    return {"this_tree": best["this"], "baseline_tree": best["baseline"],
            "closed_loop_vs_baseline_tree": round(best["this"]["sim_s_per_cpu_s"]
                                                  / best["baseline"]["sim_s_per_cpu_s"], 2),
            "closed_loop_vs_baseline_tree_wall": round(best["this"]["sim_s_per_wall_s"]
                                                       / best["baseline"]["sim_s_per_wall_s"], 2)}


def plant_alone(seconds: float) -> float:
    plant = Plant(load_params(), T_init=25.0)
    inputs = PlantInputs(P_CL_cmd=0.5e6, brake=0.0)
    t0 = time.perf_counter()
    for _ in range(int(round(seconds / plant.dt))):
        plant.step(inputs)
    return seconds / (time.perf_counter() - t0)


def env_for(tree: str | None) -> dict[str, str]:
    """The environment of a subprocess using ``tree``'s package (None: this one's)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = tree if tree is not None else str(Path(__file__).resolve().parents[1])
    return env


NEUTRAL_CWD = tempfile.gettempdir()  # 'python -m' puts the working directory first on sys.path: not a checkout


def udp_two_processes(seconds: float, tree: str | None) -> dict:
    """``dsg-hil run -i udp_multicast``: the plant here, ecu-stub as its own process, in lock-step."""
    with tempfile.TemporaryDirectory() as tmp:
        summary = Path(tmp) / "s.json"
        before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        proc = subprocess.run([sys.executable, "-m", "dsg_hil", "run", "-i", "udp_multicast", "--duration",
                               str(seconds), "--summary", str(summary)], capture_output=True, text=True,
                              env=env_for(tree), cwd=NEUTRAL_CWD, timeout=30 * seconds + 120)
        if proc.returncode != 0:
            return {"error": proc.stderr.strip().splitlines()[-1:]}
        data = json.loads(summary.read_text())
        rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    wall = data["wall_time_s"]
    return {"sim_s_per_wall_s": round(seconds / wall, 2), "wall_s": wall,
            "peak_rss_mb_children": round(max(rss, before) / 1024, 1), "rejected": data["frames"]["rejected"],
            "retries": data["frames"]["retries"]}


def startup(tree: str | None) -> dict[str, float]:
    """Median wall time of ``--help`` of every command (a fresh interpreter each time)."""
    commands = {"dsg-hil --help": ["-m", "dsg_hil", "--help"], "ecu-stub --help": ["-m", "ecu_stub", "--help"]}
    commands |= {f"dsg-hil {c} --help": ["-m", "dsg_hil", c, "--help"] for c in COMMANDS}
    times = {}
    for name, argv in commands.items():
        samples = []
        for _ in range(STARTUP_REPEATS):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, *argv], capture_output=True, check=True, env=env_for(tree),
                           cwd=NEUTRAL_CWD)
            samples.append(time.perf_counter() - t0)
        times[name] = round(statistics.median(samples), 3)
    return times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated duration in one process (default 60)")
    ap.add_argument("--udp-seconds", type=float, default=20.0, help="simulated duration on udp_multicast "
                                                                     "(default 20; 0: skip)")
    ap.add_argument("--baseline-tree", metavar="DIR", help="another checkout to time the subprocess figures with")
    ap.add_argument("--rounds", type=int, default=3, help="with --baseline-tree: runs of each tree (default 3)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--closed-loop-only", action="store_true", help=argparse.SUPPRESS)  # see closed_loop_in
    args = ap.parse_args()
    if args.closed_loop_only:
        closed_loop(0.5, "local", False)
        print(json.dumps(closed_loop(args.seconds, "local", False)))
        return

    for transport, reference in (("local", False), ("virtual", True)):  # warm up: imports, caches, first calls
        closed_loop(0.5, transport, reference)
    now = closed_loop(args.seconds, "local", reference=False)
    before = closed_loop(args.seconds, "virtual", reference=True)
    plant = plant_alone(args.seconds)
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out: dict = {
        "seconds": args.seconds,
        "closed_loop_sim_s_per_wall_s": now["sim_s_per_wall_s"],
        "closed_loop_baseline_sim_s_per_wall_s": before["sim_s_per_wall_s"],
        "closed_loop_speedup": round(now["sim_s_per_wall_s"] / before["sim_s_per_wall_s"], 2),
        "closed_loop_speedup_cpu": round(now["sim_s_per_cpu_s"] / before["sim_s_per_cpu_s"], 2),
        "closed_loop": now, "closed_loop_baseline": before,
        "share_around_physics": round(now["rest_us_per_period"] / now["period_us"], 3),
        "plant_sim_s_per_wall_s": round(plant, 2),
        "peak_rss_mb": round(rss_mb, 1),
    }
    if args.udp_seconds > 0:
        out["udp_multicast"] = udp_two_processes(args.udp_seconds, None)
        out["udp_multicast_sim_s_per_wall_s"] = out["udp_multicast"].get("sim_s_per_wall_s")
    out["startup_s"] = startup(None)
    out["startup_max_s"] = max(out["startup_s"].values())
    if args.baseline_tree:
        out["side_by_side"] = side_by_side(args.baseline_tree, args.seconds, args.rounds)
        out["closed_loop_vs_baseline_tree"] = out["side_by_side"]["closed_loop_vs_baseline_tree"]
        out["baseline_tree"] = {"path": args.baseline_tree, "startup_s": startup(args.baseline_tree)}
        if args.udp_seconds > 0:
            out["baseline_tree"]["udp_multicast"] = udp_two_processes(args.udp_seconds, args.baseline_tree)
    if args.json:
        print(json.dumps(out))
        return
    print(f"lock-step closed loop, {args.seconds:g} simulated s, 1 ms plant step, 10 ms control period")
    print(f"{'':<46}{'sim s/wall s':>13}{'us/period':>11}{'physics':>9}{'rest':>8}")
    for label, r in (("one process, generated codec, in-process bus", now),
                     ("one process, cantools codec, python-can virtual", before)):
        print(f"{label:<46}{r['sim_s_per_wall_s']:>13.1f}{r['period_us']:>11.0f}{r['physics_us_per_period']:>9.0f}"
              f"{r['rest_us_per_period']:>8.0f}")
    print(f"speed-up {out['closed_loop_speedup']:.2f}x (in CPU time {out['closed_loop_speedup_cpu']:.2f}x); "
          f"around the physics now {100 * out['share_around_physics']:.0f} % of a period")
    if "side_by_side" in out:
        sbs = out["side_by_side"]
        for label, r in (("this tree (best of the rounds)", sbs["this_tree"]),
                         (f"{args.baseline_tree} (best of the rounds)", sbs["baseline_tree"])):
            print(f"{label:<46}{r['sim_s_per_wall_s']:>13.1f}{r['period_us']:>11.0f}"
                  f"{r['physics_us_per_period']:>9.0f}{r['rest_us_per_period']:>8.0f}   {r['sim_s_per_cpu_s']:.1f} "
                  "sim s/CPU s")
        print(f"this tree against {args.baseline_tree}: {sbs['closed_loop_vs_baseline_tree']:.2f}x per CPU s, "
              f"{sbs['closed_loop_vs_baseline_tree_wall']:.2f}x in wall time")
    print(f"plant alone: {plant:.1f} sim s / wall s; peak RSS of this process {rss_mb:.0f} MB")
    if "udp_multicast" in out:
        print(f"two processes on udp_multicast ({args.udp_seconds:g} s): {out['udp_multicast']}")
        if "baseline_tree" in out and "udp_multicast" in out["baseline_tree"]:
            print(f"  ... with {args.baseline_tree}: {out['baseline_tree']['udp_multicast']}")
    print("start-up (median of 3, s):")
    for name, t in out["startup_s"].items():
        base = out.get("baseline_tree", {}).get("startup_s", {}).get(name)
        print(f"  {name:<26}{t:6.2f}" + (f"   (baseline {base:.2f})" if base is not None else ""))


if __name__ == "__main__":
    sys.argv[0] = re.sub(r"\.py$", "", sys.argv[0])
    main()
