"""Safety sweep: the creep strategy over the documented operating range, judged on the plant's TRUE plate
temperature (not the TCU's prediction). Prints one line per scenario and the violations (truth above 250 degC).

    python bench/safety_sweep.py [--n 40] [--seed 1] [--duration 300] [--jobs 2] [--json FILE]

The range (README, "The TCU"): grade 0-0.2 rad, start plate 40-150 degC, oil 40-140 degC, vehicle mass +-30 %,
desired creep speed 0.05-0.4 m/s, idle 700-1300 r/min. The scenarios are the corners that heat fastest and a
Latin hypercube over the whole box, drawn from ``--seed`` (deterministic). Each runs the real loop: plant and
ecu-stub in lockstep on python-can's virtual interface, in one process.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from dsg_hil.sim.loop import run_closed_loop
from dsg_hil.physics.params import load_params
from dsg_hil.sim.scenario import parse_scenario

T_SAFE_C = 250.0
RANGE = {  # name: (low, high)
    "grade_rad": (0.0, 0.2),
    "T_plate_c": (40.0, 150.0),
    "T_oil_c": (40.0, 140.0),
    "mass_factor": (0.7, 1.3),
    "speed_mps": (0.05, 0.4),
    "idle_rpm": (700.0, 1300.0),
}


@dataclass(frozen=True)
class Case:
    grade_rad: float
    T_plate_c: float
    T_oil_c: float
    mass_factor: float
    speed_mps: float
    idle_rpm: float

    def scenario_toml(self, duration_s: float) -> str:
        return (f'name = "sweep"\nduration_s = {duration_s}\ngrade_rad = {self.grade_rad}\n'
                f"engine_speed_rpm = {self.idle_rpm}\n"
                f"[initial]\nT_clutch_c = {self.T_plate_c}\nT_oil_c = {self.T_oil_c}\n"
                f"v_mps = 0.0\n"
                f"[[driver]]\nt_s = 0.0\ncreep_request = false\nbrake = 1.0\ndesired_speed_mps = 0.0\n"
                f"[[driver]]\nt_s = 1.0\ncreep_request = true\nbrake = 0.0\ndesired_speed_mps = {self.speed_mps}\n")


def cases(n: int, seed: int) -> list[Case]:
    """The hottest corners (steep, heavy, hot start, fast creep, low and high idle), then a Latin hypercube."""
    lo = {k: v[0] for k, v in RANGE.items()}
    hi = {k: v[1] for k, v in RANGE.items()}
    corners = [Case(**{**hi, "idle_rpm": idle}) for idle in (lo["idle_rpm"], hi["idle_rpm"])]
    corners += [Case(**{**hi, "speed_mps": lo["speed_mps"]}), Case(**{**hi, "T_oil_c": lo["T_oil_c"]}),
                Case(**{**hi, "T_plate_c": lo["T_plate_c"], "T_oil_c": lo["T_oil_c"]})]
    rng = np.random.default_rng(seed)
    m = max(n - len(corners), 0)
    columns = {}
    for key, (a, b) in RANGE.items():
        strata = (rng.permutation(m) + rng.random(m)) / max(m, 1)
        columns[key] = a + (b - a) * strata
    lhs = [Case(**{k: round(float(columns[k][i]), 4) for k in RANGE}) for i in range(m)]
    return (corners + lhs)[:n]


def run_case(case: Case, duration_s: float) -> dict:
    base = load_params()
    params = replace(base, vehicle=replace(base.vehicle, m=base.vehicle.m * case.mass_factor))
    scenario = parse_scenario(case.scenario_toml(duration_s), "sweep")
    result = run_closed_loop(scenario, params)
    s = result.summary
    return {"case": case.__dict__, "max_plate_temp_c": s["max_plate_temp_c"],
            "time_above_250_s": s.get("time_above_limit_s"), "stop_reason": s["stop_reason"],
            "stop_time_s": s.get("stop_time_s"), "handovers": len(s["handovers"]),
            "slip_time_s": s["slip_time_s"]}


def _print_row(i: int, case: Case, r: dict) -> None:
    T = r["max_plate_temp_c"]
    flag = "  <-- ABOVE 250" if max(T.values()) > T_SAFE_C else ""
    stop = "-" if r["stop_time_s"] is None else f"{r['stop_time_s']:.1f}"
    print(f"{i:>3} {case.grade_rad:6.3f} {case.T_plate_c:6.1f} {case.T_oil_c:6.1f} {case.mass_factor:5.2f} "
          f"{case.speed_mps:5.2f} {case.idle_rpm:5.0f} | {T['CL']:8.2f} {T['CH']:8.2f} {r['handovers']:>4} "
          f"{stop:>7}  {r['stop_reason']}{flag}", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=40, help="number of scenarios (default 40, the first 5 are corners)")
    ap.add_argument("--seed", type=int, default=1, help="Latin hypercube seed (default 1)")
    ap.add_argument("--duration", type=float, default=300.0, metavar="S", help="simulated s each (default 300)")
    ap.add_argument("--jobs", type=int, default=1, help="scenarios run side by side (processes, default 1)")
    ap.add_argument("--json", metavar="FILE", help="also write every result as JSON")
    args = ap.parse_args(argv)
    results, t0 = [], time.perf_counter()
    header = (f"{'#':>3} {'grade':>6} {'T_pl':>6} {'T_oil':>6} {'mass':>5} {'v':>5} {'idle':>5} | "
              f"{'max T_CL':>8} {'max T_CH':>8} {'hand':>4} {'stop s':>7}  stop")
    print(header)
    todo = cases(args.n, args.seed)
    with ProcessPoolExecutor(max_workers=max(args.jobs, 1)) as pool:
        runs = pool.map(run_case, todo, [args.duration] * len(todo))
        for i, (case, r) in enumerate(zip(todo, runs)):
            results.append(r)
            _print_row(i, case, r)
    violations = [r for r in results if max(r["max_plate_temp_c"].values()) > T_SAFE_C]
    reached = [r for r in results if max(r["max_plate_temp_c"].values()) > T_SAFE_C - 20.0]
    hottest = max(max(r["max_plate_temp_c"].values()) for r in results)
    print(f"\n{len(results)} scenarios in {time.perf_counter() - t0:.0f} s wall; {len(reached)} came within 20 K of "
          f"{T_SAFE_C:g} degC; hottest plate (truth) {hottest:.2f} degC; violations: {len(violations)}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump({"violations": len(violations), "results": results}, fh, indent=1)
    return 1 if violations else 0


if __name__ == "__main__":
    sys.exit(main())
