"""Each fault kind in the closed loop (plant and ecu-stub in lockstep on ``virtual``): what detects it, and how
the loop reacts. Windows open at t = 2 s, once the vehicle creeps (the driver asks from t = 1 s).

A lockstep plant re-sends a tick whose answer is late, and the TCU answers a repeated tick with the same
frames: a fault on TCU_CMD over a tick hits every re-send of it too (7 frames per tick given up), so the tick
goes unanswered; more than 3 such ticks in a row put the plant's hydraulics in their unpowered default.
"""

from __future__ import annotations

import logging
import math
from typing import cast

import can
import cantools
import pytest

from dsg_hil.protocol.faults import FaultError, parse_fault
from dsg_hil.sim.loop import run_closed_loop
from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.sim.scenario import load_scenario, parse_scenario
from ecu_stub.runner import TCU_USES, TcuRunner

DB = load_dbc()
SENDS_PER_TICK = 7  # a tick given up: the first transmission and RETRIES_PER_TICK re-sends


@pytest.fixture(scope="module")
def scenario():
    return load_scenario().with_duration(3.0)


def _values(m: cantools.database.can.Message, f: can.Message) -> dict[str, float]:
    return cast("dict[str, float]", m.decode(bytes(f.data), decode_choices=False))  # no container messages


class Loop:
    """A closed-loop run with its TCU kept, for the TCU's own counts."""

    def __init__(self, scenario, *faults: str, seed: int = 0, duration: float | None = None) -> None:
        tcus: list[TcuRunner] = []

        def factory(db, bus):
            tcus.append(TcuRunner(Codec(db, TCU_USES), bus))
            return tcus[0]
        if duration is not None:
            scenario = scenario.with_duration(duration)
        result = run_closed_loop(scenario, faults=[parse_fault(f) for f in faults], fault_seed=seed,
                                 tcu_factory=factory, capture=True)
        self.summary, self.frames, self.runner, self.tcu = result.summary, result.frames, result.runner, tcus[0]
        self.by_message = self.summary["frames"]["by_message"]
        self.tcu_counts = self.tcu.frame_counts()

    def series(self, message: str, signal: str, t0: float = 0.0, t1: float = math.inf) -> list[tuple[float, float]]:
        """(time, value) of a signal in the captured frames (the plant's as it sent them, the TCU's it took)."""
        m = DB.get_message_by_name(message)
        return [(round(f.timestamp, 3), float(_values(m, f)[signal]))
                for f in self.frames if f.arbitration_id == m.frame_id and t0 <= f.timestamp < t1]

    def injected(self) -> int:
        return sum(self.summary["faults"]["injected"].values())


@pytest.fixture(scope="module")
def clean(scenario):
    return Loop(scenario)


def test_the_fault_free_run_has_nothing_to_detect(clean):
    frames = clean.summary["frames"]
    assert clean.summary["faults"] == {"seed": 0, "injected": {}}
    assert frames["rejected"] == frames["lost"] == frames["duplicates"] == frames["unanswered_ticks"] == 0
    assert clean.summary["command_fallback"]["events"] == 0 and clean.tcu_counts["rejected"] == 0


@pytest.mark.parametrize("fault, cause", [("drop:TCU_CMD@2-2.1", None), ("corrupt_crc:TCU_CMD@2-2.1", "crc"),
                                          ("out_of_range:TCU_CMD.P_CL_Cmd@2-2.1", "range")])
def test_command_missing_for_more_than_3_cycles_unpowers_the_hydraulics(scenario, fault, cause):
    run = Loop(scenario, fault)
    assert run.injected() == 10 * SENDS_PER_TICK  # 10 ticks, each with its re-sends
    assert run.summary["frames"]["unanswered_ticks"] == 10
    rejected = run.by_message["TCU_CMD"]["rejected"]
    assert rejected == ({} if cause is None else {cause: 10 * SENDS_PER_TICK})  # detection
    fallback = run.summary["command_fallback"]
    assert fallback["events"] == 1 and fallback["time_s"] == pytest.approx(0.07)  # from 3 cycles on
    P_CL = dict(run.series("PLANT_PRESSURE", "P_CL"))
    assert P_CL[2.09] < 0.5 * P_CL[2.0]  # pressures decay toward 0 ...
    assert P_CL[2.5] > 0.5 * P_CL[2.0]  # ... and control resumes after the window
    commands = run.series("TCU_CMD", "SyncEcho", 2.1, 3.0)
    assert len(commands) == 90  # every tick after the window is answered again


def test_a_single_corrupt_tick_is_counted_without_fallback(scenario, clean):
    run = Loop(scenario, "corrupt_crc:TCU_CMD@2-2.01")
    assert run.by_message["TCU_CMD"]["rejected"] == {"crc": SENDS_PER_TICK} and run.injected() == SENDS_PER_TICK
    assert run.summary["frames"]["unanswered_ticks"] == 1 and run.summary["command_fallback"]["events"] == 0
    assert run.summary["max_plate_temp_c"] == pytest.approx(clean.summary["max_plate_temp_c"], abs=0.05)


@pytest.mark.parametrize("fault", ["duplicate:TCU_CMD@2-2.01", "duplicate:PLANT_VEHICLE@2-2.01"])
def test_a_duplicate_is_counted_and_ignored(scenario, clean, fault):
    run = Loop(scenario, fault)
    assert run.injected() == 1
    if "TCU_CMD" in fault:
        assert run.by_message["TCU_CMD"]["duplicates"] == 1
    else:
        assert run.tcu_counts["by_message"]["PLANT_VEHICLE"]["duplicates"] == 1
    assert run.summary["command_fallback"]["events"] == 0 and run.summary["frames"]["rejected"] == 0
    assert run.runner.out.v == clean.runner.out.v  # a duplicate changes nothing


def test_a_frozen_counter_is_rejected_until_it_moves_and_the_plant_falls_back(scenario):
    """A repeated counter is refused even after a timeout (e2e contract), so a sender whose counter froze gets
    nothing through: the command times out, the hydraulics go unpowered, and control resumes once the counter
    moves again."""
    run = Loop(scenario, "freeze_counter:TCU_CMD@2-2.1")
    assert run.by_message["TCU_CMD"]["rejected"]["counter"] >= 9 * SENDS_PER_TICK
    assert run.summary["command_fallback"]["events"] == 1
    assert [round(t * 100) for t, _ in run.series("TCU_CMD", "SyncEcho", 2.0, 2.1)] == [200]  # only the first
    assert len(run.series("TCU_CMD", "SyncEcho", 2.1, 3.0)) == 90  # every command after the window is taken


def test_delay_of_the_answer_is_taken_one_tick_late(scenario, clean):
    """In lockstep the plant waits for the answer; an answer delayed past its tick comes with the next tick:
    the tick counts as unanswered, but the command still arrives and is used, so no fallback."""
    run = Loop(scenario, "delay:TCU_CMD@2-2.1,delay_s=0.005")
    assert run.summary["frames"]["unanswered_ticks"] == 10
    assert run.summary["command_fallback"]["events"] == 0 and run.summary["frames"]["rejected"] == 0
    assert run.by_message["TCU_CMD"]["taken"] == clean.by_message["TCU_CMD"]["taken"]  # every command used
    assert run.by_message["TCU_CMD"]["duplicates"] > 0  # the delayed re-sends of the same answer


def test_wrong_dlc_is_rejected_as_dlc(scenario):
    run = Loop(scenario, "wrong_dlc:TCU_CMD@2-2.01,dlc=5")
    assert run.by_message["TCU_CMD"]["rejected"] == {"dlc": SENDS_PER_TICK}
    assert run.summary["command_fallback"]["events"] == 0
    run = Loop(scenario, "wrong_dlc:PLANT_SPEEDS@2-2.01")
    assert run.tcu_counts["by_message"]["PLANT_SPEEDS"]["rejected"] == {"dlc": run.injected()}
    assert run.tcu.incomplete_answers == 1  # the tick answered on the last good values


def test_an_outage_is_logged_once_where_it_starts_and_once_where_it_ends(scenario, caplog):
    """Each of the 50 ticks of a 0.5-s outage is answered with the last values and counted, but a sweep's log
    gets two lines for it, not fifty."""
    with caplog.at_level(logging.WARNING, logger="dsg_hil.protocol.lockstep"):
        run = Loop(scenario, "drop:PLANT_SPEEDS@2-2.5", duration=3.0)
    lines = [r.getMessage() for r in caplog.records if r.name == "dsg_hil.protocol.lockstep"]
    assert run.tcu.incomplete_answers == 50 and len(lines) == 2, lines
    assert lines[0].endswith("seen 3 times without PLANT_SPEEDS: answered with the last values")
    assert lines[1].endswith("PLANT_SPEEDS back after 50 tick(s) answered with the last values")
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="dsg_hil.protocol.lockstep"):  # due every other tick (20 ms)
        run = Loop(scenario, "drop:DRIVER@2-2.5", duration=3.0)
    lines = [r.getMessage() for r in caplog.records if r.name == "dsg_hil.protocol.lockstep"]
    assert run.tcu.incomplete_answers == 25 and len(lines) == 2, lines
    assert lines[1].endswith("DRIVER back after 25 tick(s) answered with the last values")


def test_plant_speeds_missing_puts_the_tcu_in_fault_and_back(scenario):
    run = Loop(scenario, "drop:PLANT_SPEEDS@2-2.5", duration=3.5)
    assert run.injected() > 50 and run.tcu.incomplete_answers == 50  # each tick answered on its 3rd sight
    state = dict(run.series("TCU_STATUS", "State"))
    assert state[2.0] == 2 and all(state[t] == 5 for t in (2.1, 2.2, 2.3, 2.4))  # CREEP, then FAULT
    assert state[2.5] != 5 and state[3.4] == 2  # plant frames back: engages and creeps again
    in_fault = [p for t, p in run.series("TCU_CMD", "P_CL_Cmd", 2.05, 2.5)] + \
               [p for t, p in run.series("TCU_CMD", "P_CH_Cmd", 2.05, 2.5)]
    assert in_fault and max(in_fault) == 0.0  # both clutches open
    assert run.summary["command_fallback"]["events"] == 0  # the TCU kept answering: the plant saw no fault
    status = run.series("TCU_STATUS", "FaultBits", 2.1, 2.5)
    assert all(int(bits) & 0x01 for _, bits in status)  # FAULT_PLANT_MISSING


def test_unknown_id_flood_is_ignored_and_changes_nothing(scenario, clean):
    run = Loop(scenario, "flood@2-3,rate=5")
    assert run.injected() > 1000
    assert run.tcu_counts["rejected"] == 0 and run.summary["frames"]["rejected"] == 0
    assert [(f.arbitration_id, bytes(f.data), f.timestamp) for f in run.frames] == \
           [(f.arbitration_id, bytes(f.data), f.timestamp) for f in clean.frames]


def test_stuck_vehicle_speed_passes_the_frame_checks_and_the_tcus_plausibility_vote_replaces_it(scenario, clean):
    """A plausible but wrong value with a valid counter and CRC passes every frame check. The TCU's plausibility
    checks (ecu_stub/plausibility.py) replace it by the clutch-output speeds (FaultBits 0x10, no FAULT: the two
    output speeds agree): at once, since 0.2 m/s to 0 in one frame is more than an unbraked vehicle can decelerate,
    and for good once its vote finds 40 mm between VehicleSpeed and both output speeds. Before the step check the
    TCU saw the vehicle standing for the vote's 0.2 s and pushed CL harder: the truth speed went above 2 x the
    desired speed; now it stays within 1.5 x."""
    run = Loop(scenario, "stuck:PLANT_VEHICLE.VehicleSpeed@2-3,value=0")
    assert run.summary["frames"]["rejected"] == run.tcu_counts["rejected"] == 0
    assert run.summary["command_fallback"]["events"] == 0
    assert 5 not in {s for _, s in run.series("TCU_STATUS", "State")}
    bits = dict(run.series("TCU_STATUS", "FaultBits"))
    assert not any(int(b) & 0x10 for t, b in bits.items() if t < 2.0)
    assert all(int(b) & 0x10 for t, b in bits.items() if 2.1 <= t < 3.0)
    assert run.tcu_counts["implausible"]["VehicleSpeed"] > 0 and run.tcu_counts["implausible"]["speeds"] == 0
    desired = scenario.driver_at(2.0).desired_speed_mps
    truth = dict(run.series("PLANT_VEHICLE", "VehicleSpeed"))  # the plant's frames as it sent them: the truth
    normal = dict(clean.series("PLANT_VEHICLE", "VehicleSpeed"))
    assert normal[2.9] == pytest.approx(desired, abs=0.02)
    assert max(v for t, v in truth.items() if 2.0 <= t < 3.0) < 1.5 * desired  # not overdriven
    assert truth[2.9] < 1.5 * desired


def test_same_faults_and_seed_give_the_same_frames(scenario, clean):
    """Bit for bit with the same seed; another seed hits other frames (other re-sends and rejections)."""
    runs = [Loop(scenario, "drop:TCU_CMD@2-2.5,probability=0.3", "corrupt_crc:PLANT_SPEEDS@2.2-2.6,p=0.2",
                 seed=seed) for seed in (3, 3, 4)]
    logs = [[(f.arbitration_id, bytes(f.data), f.timestamp) for f in run.frames] for run in runs]
    same = [{k: v for k, v in run.summary.items() if k not in ("interface", "wall_time_s")} for run in runs]
    assert logs[0] == logs[1] and same[0] == same[1]
    assert runs[0].summary["frames"] != runs[2].summary["frames"]
    assert runs[0].summary["faults"] != runs[2].summary["faults"] and runs[0].injected() > 0
    assert int(runs[0].series("TCU_STATUS", "FaultBits")[-1][1]) & 0x02  # the TCU reports the CRC errors seen


def test_scenario_faults_are_used_by_default_and_checked_against_the_dbc(scenario):
    text = """duration_s = 2.5
[[driver]]
t_s = 0.0
creep_request = true
desired_speed_mps = 0.2
[[fault]]
kind = "drop"
target = "TCU_CMD"
start_s = 2.0
end_s = 2.1
"""
    run = run_closed_loop(parse_scenario(text))
    assert run.summary["faults"]["injected"] == {"drop:TCU_CMD@2-2.1": 10 * SENDS_PER_TICK}
    assert run.summary["faults"]["tcu"] == run.summary["faults"]["injected"]  # the DBC sender of TCU_CMD
    bad = parse_scenario(text + '[[fault]]\nkind = "drop"\ntarget = "NO_SUCH"\n')
    with pytest.raises(FaultError, match=r"fault\[1\]: message 'NO_SUCH' is not in the DBC"):
        run_closed_loop(bad)
