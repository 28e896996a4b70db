"""Timing on a real SocketCAN bus (vcan0): the plant in real-time mode with ecu-stub as a separate process,
recorded by candump. Prints, per cyclic message, the deviation of its period from the DBC cycle time
(p50/p99/max, from candump's kernel timestamps), the command -> plant latency (TCU_CMD on the bus -> the plant
step that uses it), the real-time factor, and the lockstep closed loop over vcan0 in simulated s per wall s.

Needs vcan0; anywhere:  dsg-hil vcan -- python bench/vcan_timing.py [--duration 10] [--json]
On a busy machine:      dsg-hil vcan --load 4 -- python bench/vcan_timing.py
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from dsg_hil.protocol import load_dbc
from dsg_hil.e2e.vcan import ENV_OUTDIR, ENV_WHERE, vcan_present

BIN = Path(sys.executable).parent
BUS = ["--interface", "socketcan", "--channel", "vcan0"]


def pct(values, q):
    s = sorted(values)
    return s[min(len(s) - 1, int(q * (len(s) - 1) + 0.5))]


def run(mode: str, duration: float, work: Path) -> tuple[dict, list[tuple[float, int]]]:
    dump_path = work / f"{mode}.candump.log"
    with dump_path.open("w") as f:
        dump = subprocess.Popen(["candump", "-L", "vcan0"], stdout=f)
        time.sleep(0.3)
        tcu = subprocess.Popen([str(BIN / "ecu-stub"), *BUS, "--idle-exit", "3"])
        summary = work / f"{mode}.json"
        subprocess.run([str(BIN / "dsg-hil"), "plant", *BUS, "--mode", mode, "--duration", str(duration),
                        "--summary", str(summary)], check=True, stderr=subprocess.DEVNULL)
        tcu.wait(timeout=60)
        time.sleep(0.3)
        dump.send_signal(signal.SIGINT)
        dump.wait(timeout=10)
    frames = []
    for line in dump_path.read_text().splitlines():
        ts, _, frame = line.split()[:3]
        frames.append((float(ts.strip("()")), int(frame.split("#")[0], 16)))
    return json.loads(summary.read_text()), frames


def main() -> None:
    lines: list[str] = []

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=10.0, help="simulated seconds per run (default 10)")
    ap.add_argument("--json", action="store_true", help="the figures as one JSON object on stdout (the table: stderr)")
    args = ap.parse_args()
    figures: dict = {"duration_s": args.duration, "realtime": {"messages": {}}, "lockstep": {}}

    def say(text: str) -> None:  # the table also goes to a file: a VM console may interleave its output
        print(text, flush=True, file=sys.stderr if args.json else sys.stdout)
        lines.append(text)

    if not vcan_present():
        sys.exit("error: no vcan0 here: run it as 'dsg-hil vcan -- python bench/vcan_timing.py'")
    where = os.environ.get(ENV_WHERE, "native")
    db = load_dbc()
    work = Path(tempfile.mkdtemp(prefix="dsg-hil-timing-"))

    summary, frames = run("realtime", args.duration, work)
    times = defaultdict(list)
    for t, ident in frames:
        times[ident].append(t)
    figures["where"] = where
    figures["realtime"]["realtime_factor"] = summary["realtime_factor"]
    say(f"real-time mode on vcan0 ({where}), {args.duration:g} simulated s, plant pace "
          f"{summary['realtime_factor']:.2f} x real time")
    say(f"{'message':<16}{'cycle ms':>9}{'frames':>8}{'p50 dev ms':>12}{'p99 dev ms':>12}{'max dev ms':>12}")
    for m in db.messages:
        ts = times.get(m.frame_id, [])
        if len(ts) < 3 or m.cycle_time is None:
            say(f"{m.name:<16}{m.cycle_time:>9}{len(ts):>8}   (not sent in real time)")
            continue
        dev = [abs((b - a) * 1000.0 - m.cycle_time) for a, b in zip(ts, ts[1:])]
        figures["realtime"]["messages"][m.name] = {
            "cycle_ms": m.cycle_time, "frames": len(ts), "p50_dev_ms": round(pct(dev, 0.5), 3),
            "p99_dev_ms": round(pct(dev, 0.99), 3), "max_dev_ms": round(max(dev), 3)}
        say(f"{m.name:<16}{m.cycle_time:>9}{len(ts):>8}{pct(dev, 0.5):>12.2f}{pct(dev, 0.99):>12.2f}{max(dev):>12.2f}")
    lat = summary["command_latency_ms"]
    if lat:
        say(f"command -> plant latency (TCU_CMD on the bus -> plant step using it): p50 {lat['p50']:.2f} ms, "
              f"p99 {lat['p99']:.2f} ms, max {lat['max']:.2f} ms over {lat['n']} commands")
    say(f"command fallbacks (TCU_CMD missing 3 cycles): {summary['command_fallback']['events']}")
    figures["realtime"]["command_latency_ms"] = lat
    figures["realtime"]["command_fallbacks"] = summary["command_fallback"]["events"]

    summary, _ = run("lockstep", args.duration, work)
    wall = summary["wall_time_s"]
    say(f"lockstep closed loop over vcan0 ({where}), plant and ecu-stub as processes: {args.duration:g} simulated "
          f"s in {wall:.2f} s wall = {args.duration / wall:.2f} simulated s per wall s")
    f = summary["frames"]
    figures["lockstep"] = {"wall_s": wall, "sim_s_per_wall_s": round(args.duration / wall, 2), "retries": f["retries"],
                           "duplicates": f["duplicates"], "unanswered_ticks": f["unanswered_ticks"],
                           "probes": f["probes"]}
    say(f"lockstep re-sends {f['retries']} (per message: "
        f"{ {name: m['retries'] for name, m in f['by_message'].items() if m['retries']} }), duplicates "
        f"{f['duplicates']}, unanswered ticks {f['unanswered_ticks']}, presence probes {f['probes']}")
    out = Path(os.environ.get(ENV_OUTDIR) or work) / "vcan_timing.txt"
    out.write_text("\n".join(lines) + "\n")
    print(f"(logs in {work}; table in {out})", file=sys.stderr if args.json else sys.stdout)
    if args.json:  # also beside the table: a VM's console may interleave it with other output
        out.with_suffix(".json").write_text(json.dumps(figures) + "\n")
        print(json.dumps(figures))


if __name__ == "__main__":
    main()
