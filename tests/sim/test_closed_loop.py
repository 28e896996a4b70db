"""Plant and TCU closed loop in one process on python-can's virtual interface (no vcan needed), in lockstep.

Run with the dsg_hil plugin's fixture (``dsg_hil_run``). Judged on the plant's truth each control period
(``PlantRun.truth``), not on the TCU's prediction: plate temperatures never above 250 degC, speed within +-20 % of
its target through a handover, roll-back at brake release, tracking. The runs are short: they start with hot
clutches so the thermal events come within seconds.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import can
import pytest

from dsg_hil.physics.params import load_params
from dsg_hil.physics.plant import Plant
from dsg_hil.sim.plant_io import PLANT_USES
from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.sim.runner import PeerTimeout, PlantRunner
from dsg_hil.sim.scenario import Scenario, load_scenario, parse_scenario
from dsg_hil.testing import PlantRun, run_plant
from ecu_stub.calibration import TcuCalibration
from ecu_stub.controller import CreepController
from ecu_stub.runner import TCU_USES, TcuRunner
from ecu_stub.sensor_checks import keyon_undetected_k, oil_accuracy_at

T_SAFE = 250.0


def creep_scenario(duration: float, grade: float = 0.174, idle_rpm: float = 800.0, speed: float = 0.22,
                   T_oil: float = 90.0, T_plates: tuple[float, float] | None = None, release_s: float = 1.0):
    """Brake held until ``release_s``, then creep at ``speed`` until the end; plates (CL, CH) at ``T_plates``
    (default: the oil temperature)."""
    T_CL, T_CH = T_plates or (T_oil, T_oil)
    return parse_scenario(f"""
name = "closed-loop test"
duration_s = {duration}
grade_rad = {grade}
engine_speed_rpm = {idle_rpm}
[initial]
T_CL_c = {T_CL}
T_CH_c = {T_CH}
T_oil_c = {T_oil}
[[driver]]
t_s = 0.0
brake = 1.0
[[driver]]
t_s = {release_s}
creep_request = true
desired_speed_mps = {speed}
""")


@dataclass
class Trace:
    """Plant truth once per control period (at the tick's time) and the TCU's state as its TCU_STATUS last
    reported it (every 100 ms)."""

    t: list[float]
    v: list[float]
    v_target: list[float]
    T_CL: list[float]
    T_CH: list[float]
    state: list[str]
    T_pred: list[tuple[float, float]]  # the TCU's estimates (CL, CH), for reports only: tests judge the truth

    def handover_windows(self, after_s: float = 1.0) -> list[tuple[float, float]]:
        """(start, end + after_s) of each HANDOVER."""
        windows, start = [], None
        for t, s in zip(self.t, self.state, strict=True):
            if s == "HANDOVER" and start is None:
                start = t
            elif s != "HANDOVER" and start is not None:
                windows.append((start, t + after_s))
                start = None
        return windows

    def in_windows(self, t: float, windows) -> bool:
        return any(a <= t <= b for a, b in windows)


def trace_of(run: PlantRun, scenario: Scenario) -> Trace:
    t, s = run.truth["t"], run.signals
    states = {int(value): str(name) for value, name in
              (load_dbc().get_message_by_name("TCU_STATUS").get_signal_by_name("State").choices or {}).items()}
    state = [states.get(int(code), "?") if code == code else "?" for code in s.at("TCU_STATUS.State", t)]
    T_pred = list(zip(s.at("TCU_STATUS.T_CL_Pred", t).tolist(), s.at("TCU_STATUS.T_CH_Pred", t).tolist(), strict=True))
    return Trace(t.tolist(), run.truth["v"].tolist(), [scenario.driver_at(x).desired_speed_mps for x in t],
                 run.truth["T_CL"].tolist(), run.truth["T_CH"].tolist(), state, T_pred)


def closed_loop(scenario: Scenario | None = None, mass_factor: float = 1.0, cal: TcuCalibration | None = None,
                run: Callable[..., PlantRun] = run_plant):
    """Run the scenario (default: the shipped one) against the bundled ecu-stub in lockstep with ``run`` (the
    plugin's dsg_hil_run fixture, or run_plant); ``mass_factor`` scales the vehicle mass, ``cal`` replaces the
    TCU's shipped calibration. Returns the summary, the trace and every frame as (time, ID, data)."""
    scenario = scenario or load_scenario()
    params = {"vehicle.m": load_params().vehicle.m * mass_factor} if mass_factor != 1.0 else None
    result = run(CreepController(cal) if cal is not None else None, scenario=scenario, params=params, log=None)
    frames = [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in result.frames]
    return result.summary, trace_of(result, scenario), frames


# ---- hot clutches: the handover and the thermal limit on the plant's truth ------------------------------------
HOT = {  # name: scenario, (T_CL, T_CH) plates, rest of the network, mass factor, duration
    "paper grade, 800 r/min, 0.22 m/s": (dict(grade=0.174, idle_rpm=800, speed=0.22), (228.0, 150.0), 120.0, 1.0, 12),
    "steep, fast, heavy": (dict(grade=0.2, idle_rpm=1300, speed=0.4), (228.0, 150.0), 140.0, 1.3, 12),
    "level, slow, light": (dict(grade=0.0, idle_rpm=700, speed=0.05), (240.0, 150.0), 140.0, 0.7, 17),
}


@pytest.fixture(scope="module", params=list(HOT), ids=list(HOT))
def hot_run(request, dsg_hil_run):
    kwargs, plates, rest, mass, duration = HOT[request.param]
    scenario = creep_scenario(duration, T_oil=rest, T_plates=plates, **kwargs)
    return closed_loop(scenario, mass, run=dsg_hil_run)


def test_hot_cl_hands_over_to_ch_and_the_truth_stays_under_250(hot_run, request):
    s, trace, _ = hot_run
    assert s["handovers"] and s["handovers"][0]["from"] == "CL" and s["handovers"][0]["to"] == "CH"
    assert max(trace.T_CL) <= T_SAFE and max(trace.T_CH) <= T_SAFE
    # and not given up early: CL was used to within 15 K of the limit; in the heavy, fast launch within 20 K since the
    # margin budgets the sensor errors the plausibility checks let through, which grow with a launch's heat
    # (docs/safety.md: handed over at 230.4 degC, 238.1 before); plus what the margin grew by when it came to budget
    # an oil gain from key-on grown to T_safe (3.1 K from a key-on at 120 degC: handed over at 234.3 degC on the paper's
    # grade)
    used_k = 20.0 if request.node.callspec.id == "steep, fast, heavy" else 15.0
    T0 = HOT[request.node.callspec.id][2]
    gain_k = keyon_undetected_k(T0) * (T_SAFE / (T0 - oil_accuracy_at(T0)) - 1.0)
    assert s["handovers"][0]["T_CL_c"] >= T_SAFE - used_k - gain_k


def test_speed_stays_within_20_percent_of_its_target_through_the_handover(hot_run, request):
    if request.node.callspec.id == "steep, fast, heavy":  # known cost, open: not counted as passing
        request.applymarker(pytest.mark.xfail(strict=True, reason=(
            "the margin for undetected sensor errors (docs/safety.md) lowers CL's limit by about 8 K at "
            "this launch's heat: CL from 228 degC hands over during the launch, the speed 0.148-0.408 m/s against "
            "0.4")))
    _, trace, _ = hot_run
    windows = trace.handover_windows()
    assert windows
    speeds = [(v, vt) for t, v, vt in zip(trace.t, trace.v, trace.v_target, strict=True)
              if trace.in_windows(t, windows)]
    assert all(abs(v - vt) <= 0.2 * vt for v, vt in speeds), (min(v for v, _ in speeds), max(v for v, _ in speeds))


def test_stops_when_neither_clutch_can_take_over_with_the_truth_under_250(dsg_hil_run):
    scenario = creep_scenario(8.0, grade=0.2, idle_rpm=1300, speed=0.4, T_oil=150.0, T_plates=(232.0, 249.0))
    s, trace, _ = closed_loop(scenario, 1.3, run=dsg_hil_run)  # CH cannot take over: creep on CL, then stop
    assert s["stop_reason"] == "STOPPED_OVERHEAT" and not s["handovers"]
    assert max(trace.T_CL) <= T_SAFE and max(trace.T_CH) <= T_SAFE
    i_stop = trace.state.index("STOPPED_OVERHEAT")
    assert max(trace.T_CL[i_stop], trace.T_CH[i_stop]) >= T_SAFE - 15.0  # not before the hotter was near it
    assert abs(trace.v[-1]) < 0.01  # held by the brake


# ---- launch on the grade and tracking -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def launch_run(dsg_hil_run):
    return closed_loop(creep_scenario(12.0), run=dsg_hil_run)


def test_no_roll_back_when_the_brake_is_released_on_the_grade(launch_run):
    _, trace, _ = launch_run
    assert min(trace.v) >= -0.010
    reached = next(t for t, v in zip(trace.t, trace.v, strict=True) if v >= 0.9 * 0.22)
    assert reached < 4.0  # and it does get going


def test_speed_is_tracked_and_nothing_rejected(launch_run):
    s, trace, _ = launch_run
    settled = [(v - vt) ** 2 for t, v, vt, st in zip(trace.t, trace.v, trace.v_target, trace.state, strict=True)
               if t > 5.0 and st == "CREEP"]
    assert math.sqrt(sum(settled) / len(settled)) <= 0.005
    assert s["frames"]["rejected"] == 0 and s["frames"]["sent"] > 5000 and s["frames"]["received"] > 1000
    assert s["command_fallback"]["events"] == 0


def test_lockstep_is_deterministic_bit_for_bit(dsg_hil_run):
    _, _, a = closed_loop(load_scenario().with_duration(8.0), run=dsg_hil_run)
    _, _, b = closed_loop(load_scenario().with_duration(8.0), run=dsg_hil_run)
    assert len(a) > 3000 and a == b


def test_lockstep_without_tcu_fails_clearly():
    params, scenario, db = load_params(), load_scenario().with_duration(1.0), load_dbc()
    bus = can.Bus(interface="virtual", channel="lonely")
    runner = PlantRunner(Plant(params), scenario, Codec(db, PLANT_USES), bus)
    with pytest.raises(PeerTimeout, match="no TCU answered the lock-step presence probe within 0.5 s"):
        runner.run_lockstep(reply_timeout=0.2, startup_timeout=0.5)
    bus.shutdown()


def lockstep_with_tcu_loop(plant_codec: Codec, tcu_codec: Codec, channel: str,
                           seconds: float = 3.0) -> tuple[PlantRunner, TcuRunner, Any, list[can.Message]]:
    """A lock-step run of the default creep with the TCU in its own loop (as in the ecu-stub process) on a thread:
    (the plant's runner, the TCU, the run's summary, every frame on the bus)."""
    import threading

    plant_bus, tcu_bus, tap = (can.Bus(interface="virtual", channel=channel) for _ in range(3))
    tcu = TcuRunner(tcu_codec, tcu_bus)
    done = threading.Event()
    errors = []

    def serve():
        try:
            tcu.run(should_stop=done.is_set)
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    runner = PlantRunner(Plant(load_params()), load_scenario().with_duration(seconds), plant_codec, plant_bus)
    try:
        summary = runner.run_lockstep(reply_timeout=5.0)
    finally:
        done.set()
        thread.join(5)
        frames = []
        while (msg := tap.recv(0)) is not None:
            frames.append(msg)
        for bus in (plant_bus, tcu_bus, tap):
            bus.shutdown()
    assert not errors
    return runner, tcu, summary, frames


def test_tcu_service_loop_answers_lockstep_ticks():
    """The TCU's own loop (as in the ecu-stub process), not the in-process pump: it hears the plant's first
    frames before the first tick and must not start free-running (regression: it did, then crashed)."""
    db = load_dbc()
    runner, tcu, summary, _ = lockstep_with_tcu_loop(Codec(db, PLANT_USES), Codec(db, TCU_USES), "svc")
    assert tcu.lockstep
    assert summary.tcu_state in ("ENGAGE", "CREEP") and runner.frames()["rejected"] == 0
