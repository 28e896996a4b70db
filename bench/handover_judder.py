"""The slowest, heaviest handovers of the safety sweep's sample: is their speed dip the TCU's, or the plant's?

The 5,000-run sample on the TCU of 7ecfd2f left five runs without a frame fault or the driver's pedal beyond
+-20 % of the desired speed through a handover (r00652 25.6 %, r00857 23.8 %, r01753 20.8 %, r03843 36.4 %, r04681
39.8 %): 6.2-9.7 t on 0.145-0.227 rad at 0.051-0.086 m/s, each handed over from a hot CL to a cool CH (69-108
degC). This re-runs them (their inputs from the shipped space, as ``dsg-hil sweep dsg_hil/data/sweeps/safety.toml
--n 5000`` made them) with the shipped calibration and with the speed controller's gains scaled (``--gain``
factors; the calibration rewritten to a temporary file), and reports for each run

* the summary's ``handover_deviation_unbraked_pct`` (the drivability check, +-20 %);
* over the first steady stretch of creep on CH after its first handover (``--window`` seconds from 1 s after the
  crossover, while nothing else changes): the vehicle's speed range about its target [%], the commanded CH
  pressure's range [%] and CH's true slip range [r/min].

* through the run's worst handover as the check judges it (the crossover and ``HANDOVER_AFTER_S`` after), from the
  plant's every 1-ms step, the speed split at ``SPLIT_HZ`` (keys ``handover_...``): how much of the deviation is
  the fast part and how much the slow part (the loop's, and the friction map's); for a handover to CH, CH's true
  torque over the TCU's model of it at the lowest of its 0.1-s blocks, with the plant's mean mu and the map's there;
* in the steady window, from the plant's every 1-ms step (the drivability check's own samples), the speed split at
  ``SPLIT_HZ``: the slow part's range about the target [%] and the fast part's peak to peak [% of the target], with
  the frequency of the fast part's largest spectral peak [Hz] (the 10-ms control period sees it only as an alias);

and, with ``--lowpass TAU`` (s), the same with CH's command passed through a first-order low-pass of that time
constant through the window (the TCU as shipped otherwise): the command then carries almost nothing at the fast
part's frequency.
``--plot DIR`` draws each run's window (gains as shipped) to ``DIR/RUN_judder.png``: the speed at every step, the
10-ms samples the TCU sees, the slow part and the +-20 % band, and CH's true slip under it.

A speed range as wide with the gains halved, and CH's slip touching 0 (stick-slip), is the plant's own oscillation
(the lining's friction falling with slip: formula (6) at a cool plate), not the loop's; a fast part as large with
the command low-passed is not driven by the command at all, and one above 50 Hz is beyond any 10-ms controller. A
steady slip with a narrow range in creep but a deep dip through the crossover points at the TCU's friction map
instead (r03843).

    python bench/handover_judder.py [--gain 1.0 0.5] [--window 4.0] [--lowpass TAU] [--plot DIR]
                                    [--calibration FILE] [--json] [RUN ...]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from bisect import bisect_right
from dataclasses import replace
from operator import itemgetter
from pathlib import Path
from typing import Any

import numpy as np

from dsg_hil.common.units import CV
from dsg_hil.physics.plant import PlantOutputs
from dsg_hil.results.summary import HANDOVER_AFTER_S
from dsg_hil.sim.run import RunConfig, open_run
from dsg_hil.sim.scenario import parse_scenario
from dsg_hil.sweep.space import SAFETY_SPACE, load_space
from ecu_stub.calibration import dump_calibration, raw_sections
from ecu_stub.clutch_model import mu_lookup, nm_per_mpa

# the sample's runs (their inputs: tests/ecu_stub/sample_runs.py, shared with the closed-loop tests); the checkout
# appended to the path, so that an installed (compiled) dsg_hil still comes first
sys.path.append(str(Path(__file__).resolve().parents[1]))
from tests.ecu_stub.sample_runs import RUNS  # noqa: E402


def calibration_with_gain(factor: float, directory: Path, base: str | None = None) -> str | None:
    """A copy of the calibration ``base`` (default: the shipped one) with the speed controller's kp and ki times
    ``factor`` (``base`` itself for 1)."""
    if factor == 1.0:
        return base
    raw = raw_sections(base)
    for key in ("kp_n_per_mps", "ki_n_per_m"):
        entry = dict(raw["speed"][key])
        entry["value"] = entry["value"] * factor
        raw["speed"][key] = entry
    path = directory / f"gain_{factor:g}.toml"
    path.write_text(dump_calibration(raw, f"bench/handover_judder.py: speed gains x {factor:g}"), encoding="utf-8")
    return str(path)


SPLIT_HZ = 30.0  # the speed's slow part (the loop's, below) and fast part (above): the ~85-Hz stick-slip apart


def measure(name: str, calibration: str | None, window_s: float, lowpass_s: float | None = None,
            plot: Path | None = None) -> dict[str, Any]:
    """One run: its handover deviation, its worst handover split (:func:`_worst_handover`), and its first steady
    creep on CH after a handover (ranges, split); with ``lowpass_s``, CH's command low-passed through that window
    (:func:`_low_pass_ch`); with ``plot``, that window drawn there (:func:`_plot`)."""
    task = load_space(SAFETY_SPACE).task(0, RUNS[name])
    rows: list[tuple[float, str, str, float, float, float]] = []
    fine: list[tuple[float, ...]] = []  # (t, v, CH's slip [r/min], M_CH [N m], mu_CH) of every plant step
    model: list[tuple[float, float, float]] = []  # (t, CH's torque [N m] and mu by the TCU's model) every period
    holder: dict[str, Any] = {}

    def track(runner: Any) -> None:
        if not fine:
            _record_steps(runner.plant, fine)
        c = holder["run"].tcu.controller
        o = runner.out
        slip = (o.omega_in - o.omega_CH) * CV.RAD_S_TO_RPM
        t = runner.plant.state.t
        rows.append((t, c.state, c.active, o.v, c.P_cmd["CH"], slip))
        model.append((t, *_ch_model(c)))
        if lowpass_s is not None and "from" not in holder and len(rows) > 1 and c.state == "CREEP" \
                and c.active == "CH" and rows[-2][1] == "HANDOVER":
            holder["from"], holder["until"] = t + 1.0, t + 1.0 + window_s
            _low_pass_ch(c, holder, lowpass_s)

    config = RunConfig(scenario=parse_scenario(task["scenario"], name), params=task["params"] or None,
                       faults=task["faults"], calibration=calibration, on_period=track)
    with open_run(config) as run:
        holder["run"] = run
        summary = run.run().as_json()
    v_target = RUNS[name]["driver.desired_speed_mps"]
    start = next((t for (t, state, active, *_), (_, before, *__) in zip(rows[1:], rows)
                  if state == "CREEP" and active == "CH" and before == "HANDOVER"), None)
    out: dict[str, Any] = {"run": name, "handover_deviation_unbraked_pct": summary["handover_deviation_unbraked_pct"]}
    if start is None:
        return out
    t0 = start + HANDOVER_AFTER_S
    out.update({f"handover_{key}": value for key, value in _worst_handover(rows, fine, model, v_target).items()})
    steady = []
    for t, state, active, v, P, slip in rows:
        if t < t0:
            continue
        if t > t0 + window_s or state != "CREEP" or active != "CH":
            break
        steady.append((v, P, slip))
    if steady:
        speeds, pressures, slips = zip(*steady)
        t1 = t0 + len(steady) * 0.01
        window = _between(fine, t0 - 0.01, t1)
        out.update({"window_s": [round(t0, 2), round(t1, 2)],
                    "speed_pct": _range_pct(speeds, v_target),
                    "P_CH_cmd_pct": _range_pct(pressures, sum(pressures) / len(pressures)),
                    "slip_CH_rpm": [round(min(slips)), round(max(slips))],
                    **_split([row[1] for row in window], v_target)})
        if plot is not None:
            _plot(plot, name, window, v_target)
    return out


def _ch_model(c: Any) -> tuple[float, float]:
    """CH's torque [N m] and mu by the TCU's model (:mod:`ecu_stub.clutch_model`) at its last inputs: the map at its
    predicted plate temperature, its filtered slip and the measured pressure."""
    inp = c.inp
    if not inp.plant_valid:
        return math.nan, math.nan
    P = max(inp.P_CH_mpa, 0.0)
    mu = mu_lookup(c.cal.friction)(c._T_pred["CH"], c.mean_slip_rpm("CH", inp), P)
    return nm_per_mpa(mu, c.cal.CH) * P, mu


def _worst_handover(rows: list[tuple[float, str, str, float, float, float]], fine: list[tuple[float, ...]],
                    model: list[tuple[float, float, float]], v_target: float) -> dict[str, Any]:
    """The handover (either way) whose window as the check judges it (the crossover and ``HANDOVER_AFTER_S`` after)
    deviates most at the 1-ms steps, split (:func:`_split`), with the clutch it went to and when it began; for one to
    CH, also CH's true torque over the TCU's model of it at its lowest (:func:`_ch_against_model`)."""
    worst: dict[str, Any] = {}
    for k in range(1, len(rows)):
        if rows[k][1] == "HANDOVER" and rows[k - 1][1] != "HANDOVER":
            begun, to = rows[k - 1][0], rows[k][2]
            end = next((t for t, state, *_ in rows[k:] if state != "HANDOVER"), rows[-1][0]) + HANDOVER_AFTER_S
            speeds = [row[1] for row in _between(fine, begun, end)]
            if speeds:
                split = _split(speeds, v_target)
                if not worst or max(map(abs, split["speed_1ms_pct"])) > max(map(abs, worst["speed_1ms_pct"])):
                    worst = {"to": to, "at_s": round(begun, 2), **split,
                             **(_ch_against_model(fine, model, begun, end) if to == "CH" else {})}
    return worst


def _ch_against_model(fine: list[tuple[float, ...]], model: list[tuple[float, float, float]], begun: float,
                      end: float) -> dict[str, Any]:
    """Over (``begun``, ``end``] in 0.1-s blocks where the TCU's model gives CH a quarter of its largest torque
    there or more: the lowest ratio of CH's true torque (the mean of the block's 1-ms steps) to the model's, and in
    that block the plant's mean mu against the map's."""
    blocks = [(t0, t0 + 0.1) for t0 in np.arange(begun, end - 0.05, 0.1)]
    largest = max((m for _, m, _ in _between(model, begun, end) if m == m), default=0.0)
    best: dict[str, Any] = {}
    for lo, hi in blocks:
        steps = _between(fine, lo, hi)
        periods = [(m, mu) for _, m, mu in _between(model, lo, hi) if m == m]
        if not steps or not periods:
            continue
        m_model = sum(m for m, _ in periods) / len(periods)
        if m_model < 0.25 * largest:
            continue
        ratio = sum(row[3] for row in steps) / len(steps) / m_model
        if not best or ratio < best["CH_true_over_model"]:
            mu_true, mu_map = sum(row[4] for row in steps) / len(steps), sum(mu for _, mu in periods) / len(periods)
            best = {"CH_true_over_model": round(ratio, 3), "CH_mu_true_map": [round(mu_true, 4), round(mu_map, 4)]}
    return best


def _between(rows: list, lo: float, hi: float) -> list:
    """The rows (in time order, time first) with lo < t <= hi."""
    return rows[bisect_right(rows, lo, key=itemgetter(0)):bisect_right(rows, hi, key=itemgetter(0))]


def _record_steps(plant: Any, fine: list[tuple[float, ...]]) -> None:
    """Append (t, v, CH's slip [r/min], M_CH, mu_CH) of every step ``plant`` takes from now on to ``fine`` (its
    ``advance`` wrapped)."""
    advance = plant.advance
    names = ("t", "v", "omega_in", "omega_CH", "M_CH", "mu_CH")
    cols = [PlantOutputs._fields.index(name) for name in names]

    def recorded(inputs: Any, n_steps: int, trace: Any = None) -> Any:
        out = advance(inputs, n_steps, trace)
        rows = [tuple(getattr(out, name) for name in names)] if trace is None else trace[:, cols].tolist()
        fine.extend((t, v, (w_in - w_ch) * CV.RAD_S_TO_RPM, M, mu) for t, v, w_in, w_ch, M, mu in rows)
        return out

    plant.advance = recorded


def _plot(path: Path, name: str, window: list[tuple[float, ...]], v_target: float) -> None:
    """0.3 s of the window about its largest deviation from ``v_target``: the speed at every 1-ms step, as the TCU
    samples it every 10 ms, its slow part and the +-20 % band; CH's true slip below it."""
    from dsg_hil.paper.plots import require_matplotlib  # noqa: PLC0415 - the plots extra, only for --plot

    plt = require_matplotlib()
    t, v, slip = (np.asarray(column) for column in list(zip(*window))[:3])
    slow = _slow_part(v)
    worst = t[np.abs(v - v_target).argmax()]
    start = min(max(worst - 0.15, t[0]), t[-1] - 0.3)
    shown = (t >= start) & (t <= start + 0.3)
    sampled = shown & (np.abs(np.round(t * 100) - t * 100) < 1e-6)  # the control periods' ends
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(8, 5.5))
    top.axhspan(0.8 * v_target, 1.2 * v_target, color="0.92", label="±20 % of the desired speed")
    top.plot(t[shown], v[shown], lw=0.8, label="vehicle speed, every 1-ms step (the check's samples)")
    top.plot(t[sampled], v[sampled], "o", ms=4, label="every 10 ms (what the TCU sees: the alias)")
    top.plot(t[shown], slow[shown], lw=2.0, label=f"below {SPLIT_HZ:g} Hz (the speed loop's part)")
    top.set_ylabel("speed [m/s]")
    top.set_ylim(0.7 * v_target, 1.35 * v_target)
    top.legend(fontsize=7, loc="upper right", ncol=2)
    top.set_title(f"{name}: steady creep on a cool CH after the handover")
    bottom.plot(t[shown], slip[shown], lw=0.8, color="C3")
    bottom.set_ylabel("CH slip [r/min]")
    bottom.set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _low_pass_ch(controller: Any, holder: dict[str, Any], tau_s: float) -> None:
    """From ``holder["from"]`` to ``holder["until"]``, CH's command of ``controller`` through a first-order
    low-pass of ``tau_s`` (stepped per 10-ms cycle; CL's command 0): the controller as shipped computes, its output
    is filtered (after the window, as shipped again)."""
    update, state = controller.update, {"P": None}

    def filtered(inputs: Any, now: float) -> Any:
        out = update(inputs, now)
        if not holder["from"] - 1e-9 <= now <= holder["until"]:
            return out
        P = state["P"]
        state["P"] = P = out.P_CH_cmd_mpa if P is None else P + 0.01 / tau_s * (out.P_CH_cmd_mpa - P)
        return replace(out, P_CH_cmd_mpa=P, P_CL_cmd_mpa=0.0)

    controller.update = filtered


def _slow_part(v: np.ndarray) -> np.ndarray:
    """The part of the 1-ms speeds ``v`` below :data:`SPLIT_HZ` (their spectrum cut there)."""
    spectrum, f = np.fft.rfft(v - v.mean()), np.fft.rfftfreq(len(v), 0.001)
    return np.fft.irfft(np.where(f < SPLIT_HZ, spectrum, 0.0), len(v)) + v.mean()


def _split(speeds: list[float], v_target: float) -> dict[str, Any]:
    """The 1-ms ``speeds`` split at :data:`SPLIT_HZ`: the slow part's range about ``v_target`` [%], the fast part's
    peak to peak [% of ``v_target``] and the frequency of its largest spectral peak [Hz]."""
    v = np.asarray(speeds)
    slow = _slow_part(v)
    fast = v - slow
    spectrum, f = np.abs(np.fft.rfft(fast)), np.fft.rfftfreq(len(v), 0.001)
    peak = f[f >= SPLIT_HZ][spectrum[f >= SPLIT_HZ].argmax()]
    return {"speed_1ms_pct": _range_pct(tuple(v), v_target), "slow_pct": _range_pct(tuple(slow), v_target),
            "fast_pp_pct": round(100 * float(fast.max() - fast.min()) / v_target, 1), "fast_hz": round(float(peak))}


def _range_pct(values: tuple[float, ...], reference: float) -> list[float]:
    """The least and greatest of ``values`` relative to ``reference`` [%], to 0.1."""
    return [round(100 * (float(min(values)) / reference - 1), 1), round(100 * (float(max(values)) / reference - 1), 1)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="*", default=list(RUNS), help=f"sample runs (default: {' '.join(RUNS)})")
    ap.add_argument("--gain", type=float, nargs="+", default=[1.0, 0.5], help="speed-controller gain factors")
    ap.add_argument("--window", type=float, default=4.0, help="seconds of steady creep on CH measured")
    ap.add_argument("--calibration", metavar="FILE", help="the TCU's calibration (default: the shipped one)")
    ap.add_argument("--lowpass", type=float, metavar="TAU",
                    help="also measure each run with CH's command low-passed (time constant TAU s) in the window")
    ap.add_argument("--plot", type=Path, metavar="DIR",
                    help="draw each run's window (gains as shipped, command as is) to DIR/RUN_judder.png")
    ap.add_argument("--json", action="store_true", help="one JSON object per run and gain")
    args = ap.parse_args(argv)
    unknown = [r for r in args.runs if r not in RUNS]
    if unknown:
        print(f"handover_judder: unknown run {unknown[0]} (known: {' '.join(RUNS)})", file=sys.stderr)
        return 2
    if args.lowpass is not None and not args.lowpass > 0.0:
        print(f"handover_judder: --lowpass {args.lowpass}: a time constant > 0 s", file=sys.stderr)
        return 2
    if args.calibration is not None and not Path(args.calibration).is_file():
        print(f"handover_judder: --calibration {args.calibration}: no such file", file=sys.stderr)
        return 2
    if args.plot is not None and not args.plot.is_dir():
        print(f"handover_judder: --plot {args.plot}: not a directory", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        for factor in args.gain:
            calibration = calibration_with_gain(factor, Path(tmp), args.calibration)
            for name in args.runs:
                for lowpass in (None, args.lowpass) if args.lowpass is not None else (None,):
                    plot = args.plot / f"{name}_judder.png" if args.plot and factor == 1.0 and lowpass is None \
                        else None
                    result = {"gain": factor, "lowpass_s": lowpass,
                              **measure(name, calibration, args.window, lowpass, plot)}
                    print(json.dumps(result) if args.json else
                          "  ".join(f"{k} {v}" for k, v in result.items()), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
