"""Plant and TCU closed loop in one process on python-can's virtual interface (no vcan needed)."""

from __future__ import annotations

import can
import pytest

from dsg_hil.physics.params import load_params
from dsg_hil.physics.thermal import NODES
from dsg_hil.plant import Plant
from dsg_hil.plant_io import PLANT_USES
from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.runner import PeerTimeout, PlantRunner
from dsg_hil.scenario import load_scenario
from ecu_stub.runner import TCU_USES, TcuRunner


def closed_loop(channel: str, duration: float | None = None):
    params, scenario, db = load_params(), load_scenario(), load_dbc()
    if duration is not None:
        scenario = scenario.with_duration(duration)
    T_init = {n: scenario.T_oil_c for n in NODES} | {"CL": scenario.T_clutch_c, "CH": scenario.T_clutch_c}
    plant_bus = can.Bus(interface="virtual", channel=channel)
    tcu_bus = can.Bus(interface="virtual", channel=channel)
    frames: list[tuple[float, int, bytes]] = []
    runner = PlantRunner(Plant(params, T_init=T_init, v_init=scenario.v_mps), scenario, Codec(db, PLANT_USES),
                         plant_bus, listeners=(lambda m: frames.append((m.timestamp, m.arbitration_id, bytes(m.data))),))
    tcu = TcuRunner(Codec(db, TCU_USES), tcu_bus)
    try:
        summary = runner.run_lockstep(pump=tcu.pump)
    finally:
        plant_bus.shutdown()
        tcu_bus.shutdown()
    return summary.as_json(runner.frames(), scenario.name, "lockstep", "virtual", scenario.duration_s), frames


@pytest.fixture(scope="module")
def default_run():
    return closed_loop("closed-loop-default")


def test_creep_follows_the_strategy(default_run):
    s, _ = default_run
    first = s["handovers"][0]
    assert first["from"] == "CL" and first["to"] == "CH"  # CL first
    for h in s["handovers"]:  # each handover when the slipping clutch's prediction reached 250 degC
        assert h[f"T_{h['from']}_pred_c"] >= 249.5
        assert h[f"T_{h['to']}_pred_c"] < 240.5
    assert len(s["handovers"]) >= 2  # slips by turns: CL -> CH -> CL ...
    assert s["stop_reason"] == "STOPPED_OVERHEAT"  # and stops when neither can take over
    assert s["slip_time_s"]["CL"] > 10 and s["slip_time_s"]["CH"] > 10


def test_truth_stays_near_the_safety_limit(default_run):
    s, _ = default_run
    for clutch in ("CL", "CH"):
        assert 240.0 < s["max_plate_temp_c"][clutch] < 260.0
        assert abs(s["max_predicted_temp_c"][clutch] - s["max_plate_temp_c"][clutch]) < 10.0


def test_speed_is_tracked_and_nothing_rejected(default_run):
    s, _ = default_run
    assert s["speed_error_rms_mps"] < 0.03
    assert s["frames"]["rejected"] == 0 and s["frames"]["sent"] > 10_000 and s["frames"]["received"] > 1000
    assert s["command_fallback"]["events"] == 0


def test_lockstep_is_deterministic_bit_for_bit():
    _, a = closed_loop("det-a", duration=15.0)
    _, b = closed_loop("det-b", duration=15.0)
    assert len(a) > 5000 and a == b


def test_lockstep_without_tcu_fails_clearly():
    params, scenario, db = load_params(), load_scenario().with_duration(1.0), load_dbc()
    bus = can.Bus(interface="virtual", channel="lonely")
    runner = PlantRunner(Plant(params), scenario, Codec(db, PLANT_USES), bus)
    with pytest.raises(PeerTimeout, match="no TCU answered the lock-step presence probe within 0.5 s"):
        runner.run_lockstep(reply_timeout=0.2, startup_timeout=0.5)
    bus.shutdown()


def test_tcu_service_loop_answers_lockstep_ticks():
    """The TCU's own loop (as in the ecu-stub process), not the in-process pump: it hears the plant's first
    frames before the first tick and must not start free-running (regression: it did, then crashed)."""
    import threading

    params, scenario, db = load_params(), load_scenario().with_duration(3.0), load_dbc()
    plant_bus = can.Bus(interface="virtual", channel="svc")
    tcu_bus = can.Bus(interface="virtual", channel="svc")
    tcu = TcuRunner(Codec(db, TCU_USES), tcu_bus)
    done = threading.Event()
    errors = []

    def serve():
        try:
            tcu.run(should_stop=done.is_set)
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    runner = PlantRunner(Plant(params), scenario, Codec(db, PLANT_USES), plant_bus)
    try:
        summary = runner.run_lockstep(reply_timeout=5.0)
    finally:
        done.set()
        thread.join(5)
        plant_bus.shutdown()
        tcu_bus.shutdown()
    assert not errors and tcu.lockstep
    assert summary.tcu_state in ("ENGAGE", "CREEP") and runner.frames()["rejected"] == 0
