"""The TCU over its documented operating range, judged on the plant's truth: one JSON line per case with the
tracking RMS outside handovers, min/max speed through the handovers (and the worst deviation from the target),
roll-back at brake release, max plate temperatures (truth and the TCU's estimate), the worst truth-minus-estimate,
seconds above 250 degC and the stop time.

    python bench/tcu_envelope.py [CASE ...] [--json]     (default: all cases; each 240 simulated s)

``--json``: one JSON object, ``{"cases": {CASE: figures}}``, instead of a line per case.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout: its tests' scenarios
sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/: _cases (also under python -P)

from _cases import parse_cases  # noqa: E402
from dsg_hil.sim.scenario import load_scenario  # noqa: E402
from tests.sim.test_closed_loop import Trace, closed_loop, creep_scenario  # noqa: E402

RELEASE_S = 1.0  # the driver releases the brake (creep_scenario and the shipped scenario)


def metrics(summary: dict, tr: Trace) -> dict:
    windows = tr.handover_windows()
    inside = [tr.in_windows(t, windows) for t in tr.t]
    steady = [(v - vt) ** 2 for t, v, vt, st, w in zip(tr.t, tr.v, tr.v_target, tr.state, inside)
              if t > RELEASE_S + 5 and st == "CREEP" and not w]
    during = [(v, vt) for v, vt, w in zip(tr.v, tr.v_target, inside) if w]
    # after the TCU's 1-s start-up observer window (it does not creep before)
    worst_under = max(max(T_CL - p[0], T_CH - p[1]) for t, T_CL, T_CH, p in zip(tr.t, tr.T_CL, tr.T_CH, tr.T_pred)
                      if t > 1.0)
    rollback = -min(0.0, min(v for t, v in zip(tr.t, tr.v) if RELEASE_S <= t <= RELEASE_S + 5))
    return {
        "rms_outside_handovers_mm_s": round(1000 * math.sqrt(sum(steady) / len(steady)), 2) if steady else None,
        "handover_speed_min_max_mps": [round(min(v for v, _ in during), 3), round(max(v for v, _ in during), 3)]
        if during else None,
        "handover_worst_deviation_pct": round(100 * max(abs(v - vt) / vt for v, vt in during), 1) if during else None,
        "rollback_mm_s": round(1000 * rollback, 1),
        "handovers": [(h["t_s"], h["from"], h["T_CL_c"], h["T_CH_c"]) for h in summary["handovers"]],
        "max_truth_c": [round(max(tr.T_CL), 2), round(max(tr.T_CH), 2)],
        "max_estimate_c": [summary["max_predicted_temp_c"]["CL"], summary["max_predicted_temp_c"]["CH"]],
        "worst_truth_minus_estimate_k": round(worst_under, 2),
        "s_above_250": round(sum(0.01 for a, b in zip(tr.T_CL, tr.T_CH) if max(a, b) > 250.0), 2),
        "stop_s": next((round(t, 2) for t, st in zip(tr.t, tr.state) if st == "STOPPED_OVERHEAT"), None),
    }


def case(grade: float, idle_rpm: float, speed: float, T_plates: float, T_oil: float, mass: float = 1.0):
    return lambda: (creep_scenario(240.0, grade=grade, idle_rpm=idle_rpm, speed=speed, T_oil=T_oil,
                                   T_plates=(T_plates, T_plates)), mass)


CASES = {
    "default": lambda: (load_scenario(), 1.0),
    "paper": case(0.174, 800, 0.22, 100, 90),
    "steep_heavy_fast": case(0.2, 1300, 0.4, 150, 140, 1.3),
    "steep_heavy_slow": case(0.2, 700, 0.05, 150, 140, 1.3),
    "level_light": case(0.0, 1000, 0.22, 40, 40, 0.7),
    "hotplate_cold_oil": case(0.174, 1200, 0.1, 150, 40),
    "hot_1200": case(0.174, 1200, 0.1, 150, 140),
    "mid_heavy": case(0.1, 1000, 0.3, 120, 100, 1.3),
    "steep_light_fast": case(0.2, 1300, 0.4, 100, 90, 0.7),
}



def main() -> None:
    names, as_json = parse_cases(__doc__ or "", CASES)
    found = {}
    for name in names:
        scenario, mass = CASES[name]()
        s, trace, _ = closed_loop(scenario, mass)
        found[name] = metrics(s, trace)
        if not as_json:
            print(name, json.dumps(found[name]), flush=True)
    if as_json:
        print(json.dumps({"cases": found}))


if __name__ == "__main__":
    main()
