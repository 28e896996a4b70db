"""Closed-loop speed, side by side in one run: the lock-step closed loop (plant + ecu-stub TCU) in one process as
it runs now (generated codec, direct in-process bus) and as it ran before (cantools codec, python-can ``virtual``);
where a control period goes (the plant's physics, the plant's frame I/O and bookkeeping, the run's results, the
TCU); the plant alone; plant and TCU as two processes on udp_multicast; the start-up of every command; the peak
memory of the commands' processes and of one process running the loop (a sweep worker's).

    python bench/closed_loop_speed.py [--seconds 60] [--udp-seconds 20] [--json] [--baseline-tree DIR] [--rounds 3]
                                      [--same-cpu CPU] [--no-startup] [--loop-only] [--compiled]

``--compiled``: only the one-process closed loop of this tree as its source runs it (pure Python, as an editable
install) and as ``pip install .`` builds it (the modules of a control period compiled by mypyc, setup.py), side by
side; the build's wheel made from a copy of the tree, unpacked into a temporary directory::

    python bench/closed_loop_speed.py --compiled --seconds 240 --rounds 3

``--loop-only`` (with ``--baseline-tree``): only the one-process closed loop of the two trees side by side (real-time
factor, the period's split, runs per core-hour, peak RSS), e.g. the default 240-s creep on a loaded machine::

    python bench/closed_loop_speed.py --loop-only --baseline-tree ../main --same-cpu 1 --seconds 240

The one-process loops run as fresh processes (as a user's ``dsg-hil run``), now and before alternating,
``--rounds`` times each, the best of each kept (a busy machine only ever slows a run down; every round's figure is
in ``rounds``); so are the two-process runs. ``--baseline-tree``: also time the one-process closed loop, the
two-process run and the start-ups with the package of another checkout (e.g. the main one before these changes),
through PYTHONPATH; ``closed_loop_vs_baseline_tree`` compares them in simulated seconds per CPU second of the
process (less disturbed by other load than wall time), ``..._wall`` in wall time; ``--same-cpu CPU``: the two
trees' loops each round at once, pinned to that CPU, sharing its conditions (on a loaded machine, where one run
after another sees another load, the fairer comparison). Figures are simulated seconds
per wall second unless named per CPU second; memory is the peak resident set of the largest process of a command
(``peak_rss_mb``; the bench's own process, which also holds cantools' reference path, apart).

A period's split (``split_cpu_us``, CPU time): ``physics`` inside the plant's ``advance``, ``tcu`` inside the
in-process TCU's ``pump`` (its frame handling, receive checks, controller and answer), ``results`` inside the run
summary's ``on_period``/``on_status``, ``plant_io`` the rest (the plant's frames: values, encoding, sending, the
lock-step wait and receive checks, its inputs; the timers' own cost, under 1 us, included); in the compiled build,
whose compiled callers do not go through a wrapped method, ``physics`` and the rest (``compiled``).
``runs_per_core_hour``: runs of the default creep (240 s) per CPU hour, the loop alone and with each run's set-up
in a warm process (``..._with_setup``: building the plant, the TCU and the bus, as a sweep worker does per run; the
process's own start-up, imports and compiled code, it pays once). ``loop_peak_rss_mb``: the peak resident set of the
process that ran the loop.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable
from importlib.machinery import EXTENSION_SUFFIXES
from pathlib import Path

from dsg_hil.physics.params import load_params
from dsg_hil.physics.plant import Plant, PlantInputs
from dsg_hil.results.summary import RunSummary
from dsg_hil.sim.loop import run_closed_loop
from dsg_hil.sim.scenario import load_scenario
from ecu_stub.runner import TcuRunner

COMMANDS = ("run", "plant", "bridge", "dbc", "vcan", "validate", "calibrate", "params", "report")
STARTUP_REPEATS = 3
CREEP_S = 240.0  # the default creep's duration (runs per core-hour)


def _timed(cls: type, name: str, inside: list[float]) -> Callable[[], None] | None:
    """Wrap ``cls.name`` to add the wall and CPU time spent inside it to ``inside`` ([wall, CPU]); returns the
    undo (None for a class compiled by mypyc, left as it is)."""
    inner = getattr(cls, name)

    def timed(*args, **kwargs):
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            return inner(*args, **kwargs)
        finally:
            inside[0] += time.perf_counter() - t0
            inside[1] += time.process_time() - c0

    if _compiled_module(cls.__module__):  # compiled by mypyc (setup.py): its callers call the method itself, not a
        return None  # replacement: no split
    setattr(cls, name, timed)
    return lambda: setattr(cls, name, inner)


def closed_loop(seconds: float, transport: str, reference: bool) -> dict:
    """One in-process lock-step run: sim s per wall s (and per CPU s of this process, less disturbed by other
    load on the machine); the time inside the plant's advance (a control period's steps in one call) against the
    rest of each period; a period's CPU time split: physics, the TCU (its pump), the results (the run summary's
    updates) and the plant's I/O (the rest)."""
    scenario = load_scenario().with_duration(seconds)
    physics, tcu, results = [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]  # wall, CPU
    undo = [_timed(Plant, "advance", physics), _timed(TcuRunner, "pump", tcu),
            _timed(RunSummary, "on_period", results), _timed(RunSummary, "on_status", results)]
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        result = run_closed_loop(scenario, transport=transport, reference_codec=reference)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        for restore in undo:
            if restore is not None:
                restore()
    periods, run = result.runner.n_periods, result.summary["wall_time_s"]  # run: the periods, without set-up
    loop_cpu = cpu * run / wall if wall > 0 else cpu  # the periods' CPU time (set-up taken out in proportion)
    us = 1e6 / periods
    split = {"physics": physics[1], "plant_io": loop_cpu - physics[1] - tcu[1] - results[1], "results": results[1],
             "tcu": tcu[1]} if None not in undo else {"physics": physics[1], "compiled": loop_cpu - physics[1]}
    return {"sim_s_per_wall_s": round(seconds / wall, 2), "sim_s_per_cpu_s": round(seconds / cpu, 2),
            "loop_sim_s_per_cpu_s": round(seconds / loop_cpu, 2), "wall_s": round(wall, 3),
            "setup_s": round(wall - run, 3), "period_us": round(us * run, 1),
            "physics_us_per_period": round(us * physics[0], 1), "rest_us_per_period": round(us * (run - physics[0]), 1),
            "rest_cpu_us_per_period": round(us * (cpu - physics[1]), 1),
            "period_cpu_us": round(us * loop_cpu, 1), "compiled": compiled(),
            "split_cpu_us": {k: round(us * v, 1) for k, v in split.items()},
            "runs_per_core_hour": round(3600.0 * seconds / loop_cpu / CREEP_S),
            "runs_per_core_hour_with_setup": round(3600.0 / (CREEP_S * loop_cpu / seconds + cpu - loop_cpu)),
            "frames_sent": result.summary["frames"]["sent"],
            "loop_peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}


def compiled() -> bool:
    """Whether the TCU runs compiled (a regular install of this package: setup.py), not from its source."""
    return _compiled_module(TcuRunner.__module__)


def _compiled_module(name: str) -> bool:
    """Whether the imported module ``name`` is an extension module (compiled by mypyc, setup.py)."""
    return (sys.modules[name].__file__ or "").endswith(tuple(EXTENSION_SUFFIXES))


def compiled_site(out: Path) -> str:
    """This tree built as ``pip install .`` builds it (the closed loop compiled, setup.py), from a copy of its sources
    (as a fresh clone: no ``build/`` of an earlier build), its wheel unpacked into ``out``: a directory for
    PYTHONPATH."""
    root, src = Path(__file__).resolve().parents[1], out / "src"
    shutil.copytree(root, src, ignore=shutil.ignore_patterns(".*", "build", "dist", "out", "*.egg-info", "__pycache__"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(src)], check=True)
    (wheel,) = out.glob("dsg_hil-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        zf.extractall(out / "site")
    return str(out / "site")


def closed_loop_argv(seconds: float, transport: str = "local", reference: bool = False) -> list[str]:
    """The command line of :func:`closed_loop` in a fresh process (this script, ``--closed-loop-only``)."""
    return [sys.executable, str(Path(__file__).resolve()), "--closed-loop-only", "--seconds", str(seconds),
            "--transport", transport] + (["--reference-codec"] if reference else [])


def closed_loop_in(tree: str | None, seconds: float, transport: str = "local", reference: bool = False) -> dict:
    """:func:`closed_loop` in a fresh process on ``tree``'s package (None: this one's)."""
    proc = subprocess.run(closed_loop_argv(seconds, transport, reference), capture_output=True, text=True,
                          check=True, env=env_for(tree), cwd=NEUTRAL_CWD, timeout=60 * seconds + 120)
    return json.loads(proc.stdout)


def closed_loops_on_one_cpu(trees: list[str | None], seconds: float, cpu: int) -> list[dict]:
    """:func:`closed_loop` on each tree's package, in fresh processes started together and pinned to ``cpu``: they
    share its conditions time slice by time slice (on a loaded machine, where runs one after the other see
    different loads, the fairer comparison)."""
    procs = [subprocess.Popen(closed_loop_argv(seconds), stdout=subprocess.PIPE, text=True, env=env_for(tree),
                              cwd=NEUTRAL_CWD, preexec_fn=lambda: os.sched_setaffinity(0, {cpu}))
             for tree in trees]
    outs = [proc.communicate(timeout=120 * seconds + 240)[0] for proc in procs]
    if any(proc.returncode for proc in procs):
        raise RuntimeError(f"a closed loop on CPU {cpu} failed")
    return [json.loads(out) for out in outs]


def best_of(runs: list[dict], key: str) -> dict:
    """The fastest of ``runs`` by ``key`` (a busy machine only ever slows a run down), with every round's figure."""
    best = dict(max(runs, key=lambda r: r[key]))
    best["rounds"] = [r[key] for r in runs]
    return best


def side_by_side(configs: dict[str, tuple[str | None, str, bool]], seconds: float, rounds: int,
                 key: str) -> dict[str, dict]:
    """The one-process closed loop of each configuration (tree, transport, reference codec) in fresh processes,
    alternating, ``rounds`` times each; the best run of each by ``key``."""
    runs: dict[str, list[dict]] = {name: [] for name in configs}
    for _ in range(rounds):
        for name, (tree, transport, reference) in configs.items():
            runs[name].append(closed_loop_in(tree, seconds, transport, reference))
    return {name: best_of(r, key) for name, r in runs.items()}


def tree_vs_tree(tree: str, seconds: float, rounds: int, cpu: int | None = None) -> dict:
    """The one-process closed loop on this package and on ``tree``'s, compared per CPU second of the process; with
    ``cpu``, both at once on that CPU each round (:func:`closed_loops_on_one_cpu`)."""
    if cpu is None:
        best = side_by_side({"this": (None, "local", False), "baseline": (tree, "local", False)}, seconds, rounds,
                            "sim_s_per_cpu_s")
    else:
        pairs = [closed_loops_on_one_cpu([None, tree], seconds, cpu) for _ in range(rounds)]
        best = {name: best_of([pair[i] for pair in pairs], "sim_s_per_cpu_s")
                for i, name in enumerate(("this", "baseline"))}
    return {"this_tree": best["this"], "baseline_tree": best["baseline"],
            "closed_loop_vs_baseline_tree": round(best["this"]["sim_s_per_cpu_s"]
                                                  / best["baseline"]["sim_s_per_cpu_s"], 2),
            "closed_loop_vs_baseline_tree_wall": round(best["this"]["sim_s_per_wall_s"]
                                                       / best["baseline"]["sim_s_per_wall_s"], 2)}


def dsg_hil_run(seconds: float, summary: str, *options: str) -> list[str]:
    """The command line of ``dsg-hil run`` for ``seconds`` of the default creep, its summary to ``summary``."""
    return [sys.executable, "-m", "dsg_hil", "run", *options, "--duration", str(seconds), "--summary", summary]


def peak_rss_mb(argv: list[str]) -> float:
    """Peak resident memory [MB] of the largest process ``argv`` runs (itself or a child it waits for, such as
    the ecu-stub that ``dsg-hil run -i udp_multicast`` starts), measured from a fresh wrapper process."""
    wrapper = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, capture_output=True); "
               "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    proc = subprocess.run([sys.executable, "-c", wrapper, *argv], capture_output=True, text=True, check=True,
                          env=env_for(None), cwd=NEUTRAL_CWD)
    return round(int(proc.stdout) / 1024, 1)


def plant_alone(seconds: float) -> float:
    """The plant stepped one ``step()`` call per 1-ms step, after a warm-up (compiled code loaded)."""
    plant = Plant(load_params(), T_init=25.0)
    inputs = PlantInputs(P_CL_cmd=0.5e6, brake=0.0)
    for _ in range(100):
        plant.step(inputs)
    t0 = time.perf_counter()
    for _ in range(int(round(seconds / plant.dt))):
        plant.step(inputs)
    return seconds / (time.perf_counter() - t0)


def env_for(tree: str | None) -> dict[str, str]:
    """The environment of a subprocess using ``tree``'s package (None: this one's)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = tree if tree is not None else str(Path(__file__).resolve().parents[1])
    env.setdefault("OPENBLAS_NUM_THREADS", "1")  # as dsg-hil's commands run (dsg_hil.common.cli.one_blas_thread)
    return env


NEUTRAL_CWD = tempfile.gettempdir()  # 'python -m' puts the working directory first on sys.path: not a checkout


def udp_two_processes(seconds: float, tree: str | None) -> dict:
    """``dsg-hil run -i udp_multicast``: the plant here, ecu-stub as its own process, in lock-step."""
    with tempfile.TemporaryDirectory() as tmp:
        summary = Path(tmp) / "s.json"
        proc = subprocess.run(dsg_hil_run(seconds, str(summary), "-i", "udp_multicast"), capture_output=True,
                              text=True, env=env_for(tree), cwd=NEUTRAL_CWD, timeout=30 * seconds + 120)
        if proc.returncode != 0:
            return {"error": proc.stderr.strip().splitlines()[-1:]}
        data = json.loads(summary.read_text())
    wall = data["wall_time_s"]
    return {"sim_s_per_wall_s": round(seconds / wall, 2), "wall_s": wall, "rejected": data["frames"]["rejected"],
            "retries": data["frames"]["retries"]}


ECHO = """
import sys, can
bus = can.Bus(interface="udp_multicast", channel=sys.argv[1], port=int(sys.argv[2]))
print("ready", flush=True)
while (msg := bus.recv(5.0)) is not None:
    if msg.arbitration_id == 0x100:
        bus.send(can.Message(arbitration_id=0x101, data=msg.data, is_extended_id=False))
    elif msg.arbitration_id == 0x102:
        break
bus.shutdown()
"""


def udp_primitives(n: int = 2000) -> dict[str, float]:
    """The floor under a lock-step tick on python-can's udp_multicast, from its own calls: a frame's send, the
    receive of a frame already waiting (the sender's own, looped back by multicast), and the round trip to an
    echoing process (send, its wake-up, receive, answer, our wake-up) [us, medians of ``n``]."""
    import can

    from dsg_hil.protocol.bus import fresh_udp_group

    group = fresh_udp_group()
    echo = subprocess.Popen([sys.executable, "-c", ECHO, group["channel"], str(group["port"])],
                            stdout=subprocess.PIPE, text=True, cwd=NEUTRAL_CWD)
    assert echo.stdout is not None and echo.stdout.readline().strip() == "ready"
    bus = can.Bus(interface="udp_multicast", channel=group["channel"], port=group["port"])
    send, own, trip = [], [], []
    try:
        ping = can.Message(arbitration_id=0x100, data=bytes(8), is_extended_id=False)
        for _ in range(n):
            t0 = time.perf_counter()
            bus.send(ping)
            t1 = time.perf_counter()
            while (msg := bus.recv(1.0)) is not None and msg.arbitration_id != 0x100:
                pass  # the first frame back is our own, looped back
            t2 = time.perf_counter()
            while (msg := bus.recv(1.0)) is not None and msg.arbitration_id != 0x101:
                pass
            t3 = time.perf_counter()
            send.append(t1 - t0)
            own.append(t2 - t1)
            trip.append(t3 - t0)
        bus.send(can.Message(arbitration_id=0x102, is_extended_id=False))
    finally:
        bus.shutdown()
        echo.wait(timeout=10)
    return {name: round(1e6 * statistics.median(v), 1)
            for name, v in (("send_us", send), ("receive_own_us", own), ("round_trip_us", trip))}


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
    ap.add_argument("--same-cpu", type=int, metavar="CPU", help="run this tree's and the baseline tree's closed "
                    "loops together, pinned to this CPU (fairer on a loaded machine)")
    ap.add_argument("--rounds", type=int, default=3, help="runs of each configuration, the best kept (default 3)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--no-startup", action="store_true", help="skip the start-up times of the commands")
    ap.add_argument("--loop-only", action="store_true", help="with --baseline-tree: only the one-process closed "
                    "loop of the two trees, side by side")
    ap.add_argument("--compiled", action="store_true", help="only the one-process closed loop of this tree, pure "
                    "Python (its source) and compiled (built as 'pip install .' builds it: setup.py), side by side")
    ap.add_argument("--closed-loop-only", action="store_true", help=argparse.SUPPRESS)  # see closed_loop_in
    ap.add_argument("--transport", default="local", help=argparse.SUPPRESS)
    ap.add_argument("--reference-codec", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.closed_loop_only:
        closed_loop(0.5, args.transport, args.reference_codec)  # warm up: imports, caches, first calls
        print(json.dumps(closed_loop(args.seconds, args.transport, args.reference_codec)))
        return

    if args.compiled:
        with tempfile.TemporaryDirectory() as tmp:
            sbs = tree_vs_tree(compiled_site(Path(tmp)), args.seconds, args.rounds, args.same_cpu)
        pure, built = sbs["this_tree"], sbs["baseline_tree"]
        ratio = {"compiled_vs_pure": round(built["sim_s_per_cpu_s"] / pure["sim_s_per_cpu_s"], 2),
                 "compiled_vs_pure_wall": round(built["sim_s_per_wall_s"] / pure["sim_s_per_wall_s"], 2)}
        if args.json:
            print(json.dumps({"seconds": args.seconds, "rounds": args.rounds, "pure": pure, "compiled": built,
                              **ratio}))
        else:
            print_side_by_side(sbs, args.seconds, args.rounds, "the compiled build", ("pure Python", "compiled"))
            print(f"compiled: {ratio['compiled_vs_pure']:.2f}x the pure Python's speed per CPU s, "
                  f"{ratio['compiled_vs_pure_wall']:.2f}x in wall time")
        return

    if args.loop_only:
        if not args.baseline_tree:
            ap.error("--loop-only needs --baseline-tree")
        sbs = tree_vs_tree(args.baseline_tree, args.seconds, args.rounds, args.same_cpu)
        if args.json:
            print(json.dumps({"seconds": args.seconds, "rounds": args.rounds, "side_by_side": sbs}))
        else:
            print_side_by_side(sbs, args.seconds, args.rounds, args.baseline_tree)
        return

    best = side_by_side({"now": (None, "local", False), "before": (None, "virtual", True)}, args.seconds,
                        args.rounds, "sim_s_per_wall_s")
    now, before = best["now"], best["before"]
    plant = plant_alone(args.seconds)
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out: dict = {
        "seconds": args.seconds, "rounds": args.rounds,
        "closed_loop_sim_s_per_wall_s": now["sim_s_per_wall_s"],
        "closed_loop_baseline_sim_s_per_wall_s": before["sim_s_per_wall_s"],
        "closed_loop_speedup": round(now["sim_s_per_wall_s"] / before["sim_s_per_wall_s"], 2),
        "closed_loop_speedup_cpu": round(now["sim_s_per_cpu_s"] / before["sim_s_per_cpu_s"], 2),
        "closed_loop": now, "closed_loop_baseline": before,
        "share_around_physics": round(now["rest_us_per_period"] / now["period_us"], 3),
        "plant_sim_s_per_wall_s": round(plant, 2),
        "peak_rss_mb_this_bench": round(rss_mb, 1),
        "peak_rss_mb": {"dsg-hil run": peak_rss_mb(dsg_hil_run(args.seconds, os.devnull))},
    }
    if args.udp_seconds > 0:
        udp = [udp_two_processes(args.udp_seconds, None) for _ in range(args.rounds)]
        failed = [u["error"] for u in udp if "error" in u]
        out["udp_multicast"] = {"error": failed[0], "failed_rounds": len(failed)} if failed \
            else best_of(udp, "sim_s_per_wall_s")
        out["udp_multicast_sim_s_per_wall_s"] = out["udp_multicast"].get("sim_s_per_wall_s")
        out["udp_multicast_primitives"] = udp_primitives()
        out["peak_rss_mb"]["dsg-hil run -i udp_multicast (plant, ecu-stub)"] = peak_rss_mb(
            dsg_hil_run(args.seconds, os.devnull, "-i", "udp_multicast"))
    out["peak_rss_mb_max"] = max(out["peak_rss_mb"].values())
    if not args.no_startup:
        out["startup_s"] = startup(None)
        out["startup_max_s"] = max(out["startup_s"].values())
    if args.baseline_tree:
        out["side_by_side"] = tree_vs_tree(args.baseline_tree, args.seconds, args.rounds, args.same_cpu)
        out["closed_loop_vs_baseline_tree"] = out["side_by_side"]["closed_loop_vs_baseline_tree"]
        out["baseline_tree"] = {"path": args.baseline_tree}
        if not args.no_startup:
            out["baseline_tree"]["startup_s"] = startup(args.baseline_tree)
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
    print(f"best of {args.rounds} fresh processes each; rounds: now {now['rounds']}, before {before['rounds']}")
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
        runs = [("this tree", sbs["this_tree"]), ("baseline tree", sbs["baseline_tree"])]
    else:
        runs = [("this tree", now)]
    print(f"a period in CPU us, loop alone (x real time per CPU s; runs of the {CREEP_S:g}-s creep per core-hour, "
          "+ each run's set-up; peak RSS of the loop's process):")
    for label, r in runs:
        split = "  ".join(f"{k} {v:5.1f}" for k, v in r["split_cpu_us"].items())
        print(f"  {label:<14}{r['period_cpu_us']:7.1f} = {split}   ({r['loop_sim_s_per_cpu_s']:.0f}x; "
              f"{r['runs_per_core_hour']} / {r['runs_per_core_hour_with_setup']} runs; {r['loop_peak_rss_mb']:.0f} MB)")
    print(f"plant alone, one step per call: {plant:.1f} sim s / wall s")
    print("peak RSS (MB): " + ", ".join(f"{k} {v:.0f}" for k, v in out["peak_rss_mb"].items()))
    if "udp_multicast" in out:
        print(f"two processes on udp_multicast ({args.udp_seconds:g} s): {out['udp_multicast']}")
        print(f"  python-can udp_multicast, median per call: {out['udp_multicast_primitives']}")
        if "baseline_tree" in out and "udp_multicast" in out["baseline_tree"]:
            print(f"  ... with {args.baseline_tree}: {out['baseline_tree']['udp_multicast']}")
    if "startup_s" not in out:
        return
    print("start-up (median of 3, s):")
    for name, t in out["startup_s"].items():
        base = out.get("baseline_tree", {}).get("startup_s", {}).get(name)
        print(f"  {name:<26}{t:6.2f}" + (f"   (baseline {base:.2f})" if base is not None else ""))


def print_side_by_side(sbs: dict, seconds: float, rounds: int, baseline: str,
                       labels: tuple[str, str] = ("this tree", "baseline tree")) -> None:
    """The lines of ``--loop-only`` (and ``--compiled``): each tree's real-time factor, its period split (none for
    a compiled one), runs per core-hour, peak RSS."""
    print(f"one-process lock-step closed loop (plant + ecu-stub, in-process bus), {seconds:g} simulated s of the "
          f"default creep, best of {rounds} fresh processes per tree")
    print(f"{'':<16}{'x real time':>12}{'x per CPU s':>12}{'CPU us/period':>14}   split (CPU us)"
          f"{'':<40}{'runs/core-h':>12}{'+ set-up':>9}{'RSS MB':>8}")
    for label, r in zip(labels, (sbs["this_tree"], sbs["baseline_tree"])):
        split = "  ".join(f"{k} {v:5.1f}" for k, v in r["split_cpu_us"].items())
        print(f"{label:<16}{r['sim_s_per_wall_s']:>12.1f}{r['loop_sim_s_per_cpu_s']:>12.1f}{r['period_cpu_us']:>14.1f}"
              f"   {split:<54}{r['runs_per_core_hour']:>12}{r['runs_per_core_hour_with_setup']:>9}"
              f"{r['loop_peak_rss_mb']:>8.0f}")
    print(f"this tree against {baseline}: {sbs['closed_loop_vs_baseline_tree']:.2f}x per CPU s, "
          f"{sbs['closed_loop_vs_baseline_tree_wall']:.2f}x in wall time (rounds, x per CPU s: this "
          f"{sbs['this_tree']['rounds']}, baseline {sbs['baseline_tree']['rounds']})")


if __name__ == "__main__":
    sys.argv[0] = re.sub(r"\.py$", "", sys.argv[0])
    main()
