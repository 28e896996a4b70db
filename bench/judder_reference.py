"""Is CH's 85-Hz judder at a slow, heavy creep the plant's equations', or its 1-ms stepping's?

``bench/handover_judder.py`` found the fast part of the speed through the sample's slowest handovers to a cool CH to
be a stick-slip of CH at 84-85 Hz. This runs one of those sample runs in lock-step up to ``T0`` (steady creep on CH),
copies the plant there, and follows it ``--span`` seconds with the inputs held (the TCU's last pressures, the grade,
the engine's request) twice: with the plant's own fixed 1-ms steps (exact linear steps, friction held over a step,
stick/slip by its implicit contact law) and with ``dsg_hil.physics.continuous.solve_hybrid`` (the same equations in
continuous time, Radau at a tight tolerance, stick/slip as events). For each: CH's slip range, the vehicle speed's
range, its fast part (the speed minus its mean over one 12-ms period: the held inputs let the slow part drift) with
its spectral peak and its peak to peak as a share of the desired speed, over the second half of the span.

The same judder from both says it is formula (6) on Table I's driveline, not the step; its fast part against the
+-20 % band of the drivability check says how much of the band is left to any controller (none acts here: the
inputs are held).

    python bench/judder_reference.py RUN T0 [--span 0.5] [--json]      e.g. r01753 26.0, r00857 27.0
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[1]))  # the checkout, after an installed dsg_hil
from tests.ecu_stub.sample_runs import RUNS  # noqa: E402 - the sample runs' inputs, one place

from dsg_hil.common.units import CV  # noqa: E402
from dsg_hil.physics.continuous import solve_hybrid  # noqa: E402
from dsg_hil.physics.powertrain import IDX, vehicle_speed  # noqa: E402
from dsg_hil.sim.run import RunConfig, open_run  # noqa: E402
from dsg_hil.sim.scenario import parse_scenario  # noqa: E402
from dsg_hil.sweep.space import SAFETY_SPACE, load_space  # noqa: E402

PERIOD_STEPS = 12  # one 84-Hz period at the 1-ms step, about: the fast part is the speed minus its mean over it


class _Reached(Exception):
    """The run reached T0 (its plant and inputs copied): stop it."""


def plant_at(name: str, t0: float) -> tuple[Any, Any]:
    """A copy of the plant of sample run ``name`` in lock-step at ``t0`` and the inputs it was being driven with."""
    task = load_space(SAFETY_SPACE).task(0, RUNS[name])
    held: dict[str, Any] = {}

    def track(runner: Any) -> None:
        if runner.plant.state.t >= t0:
            held["plant"], held["inputs"] = copy.deepcopy(runner.plant), runner._held
            raise _Reached

    config = RunConfig(scenario=parse_scenario(task["scenario"], name), params=task["params"] or None,
                       faults=task["faults"], on_period=track)
    try:
        with open_run(config) as run:
            run.run()
    except _Reached:
        pass
    if "plant" not in held:
        raise SystemExit(f"judder_reference: {name} ended before t = {t0} s")
    return held["plant"], held["inputs"]


def describe(slip_rpm: np.ndarray, v: np.ndarray, target: float) -> dict[str, Any]:
    """CH's slip range [r/min], the speed's range [m/s], its fast part's spectral peak [Hz] and peak to peak [% of
    target]; the second half of the span."""
    slip, v = slip_rpm[len(slip_rpm) // 2:], v[len(v) // 2:]
    k = PERIOD_STEPS
    fast = (v - np.convolve(v, np.ones(k) / k, mode="same"))[k:-k]
    peak_hz = np.fft.rfftfreq(len(fast), 1e-3)[np.abs(np.fft.rfft(fast - fast.mean())).argmax()]
    return {"slip_CH_rpm": [round(float(slip.min()), 1), round(float(slip.max()), 1)],
            "speed_mps": [round(float(v.min()), 4), round(float(v.max()), 4)], "fast_hz": round(float(peak_hz), 1),
            "fast_pp_pct": round(float(100 * (fast.max() - fast.min()) / target), 1)}


def _line(d: dict[str, Any]) -> str:
    (s0, s1), (v0, v1) = d["slip_CH_rpm"], d["speed_mps"]
    return (f"CH slip {s0:6.1f}..{s1:6.1f} r/min, speed {1e3 * v0:5.1f}..{1e3 * v1:5.1f} mm/s, fast part at "
            f"{d['fast_hz']:3.0f} Hz, {d['fast_pp_pct']:5.1f} % of the target peak to peak")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", choices=sorted(RUNS), help="a sample run of bench/handover_judder.py")
    ap.add_argument("t0", type=float, help="when to copy the plant [s]: in steady creep on CH")
    ap.add_argument("--span", type=float, default=0.5, help="seconds followed with the inputs held")
    ap.add_argument("--json", action="store_true", help="one JSON object instead of lines")
    args = ap.parse_args(argv)
    plant, inputs = plant_at(args.run, args.t0)
    target = RUNS[args.run]["driver.desired_speed_mps"]
    stepped = copy.deepcopy(plant)
    rows = [(o.t, (o.omega_in - o.omega_CH) * CV.RAD_S_TO_RPM, o.v)
            for o in (stepped.step(inputs) for _ in range(round(args.span / stepped.dt)))]
    t, slip, v = (np.array(column) for column in zip(*rows))
    t_eval = t - plant.state.t
    t_eval = t_eval[t_eval <= args.span - 1e-9]
    y, changes = solve_hybrid(copy.deepcopy(plant), lambda _t: inputs, [args.span], t_eval, rtol=1e-8)
    pt, vehicle = plant.params.powertrain, plant.params.vehicle
    slip_ref = (y[:, IDX["1"]] - y[:, IDX["3"]]) * CV.RAD_S_TO_RPM
    v_ref = np.array([vehicle_speed(w, pt.i_b, vehicle.r_w) for w in y[:, IDX["5"]]])
    n = len(t_eval)
    steps, reference = describe(slip[:n], v[:n], target), describe(slip_ref, v_ref, target)
    if args.json:
        print(json.dumps({"run": args.run, "t0_s": plant.state.t, "steps": steps, "solve_ivp": reference,
                          "stick_slip_changes": changes}))
        return 0
    print(f"{args.run} from t = {plant.state.t:.3f} s, inputs held: {inputs}")
    print(f"  1-ms steps:  {_line(steps)}")
    print(f"  solve_ivp:   {_line(reference)} ({changes} stick/slip changes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
