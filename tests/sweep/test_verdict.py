"""The judgement of a run on the truth: each violation, and what does not count as one."""

from __future__ import annotations

import pytest

from dsg_hil.protocol.codec import load_dbc
from dsg_hil.protocol.faults import parse_fault
from dsg_hil.sweep.space import SAFETY_SPACE, load_space
from dsg_hil.sim.scenario import parse_scenario
from dsg_hil.sweep.worker import pedal_while_stopping, run_task
from dsg_hil.sweep.verdict import (LIMITS, UnexplainedFault, fault_windows, in_windows, objective_value, summary_row,
                                   verdict, violations)

SUMMARY = {"scenario": "s", "max_plate_temp_c": {"CL": 251.2, "CH": 180.0}, "time_above_limit_s": {"CL": 0.4,
           "CH": 0.0}, "handovers": [{"t_s": 3.0}], "phases": [], "rollback_m": 0.0, "stop_reason": "end_of_record",
           "frames": {"sent": 10}}


def test_the_summary_flattens_to_one_row():
    row = summary_row(SUMMARY)
    assert row["max_plate_temp_c"] == 251.2 and row["max_plate_temp_c.CL"] == 251.2
    assert row["time_above_limit_s.CL"] == 0.4 and row["n_handovers"] == 1 and row["n_phases"] == 0
    assert row["frames"] == '{"sent": 10}' and row["max_speed_mps"] is None  # a metric not there: None
    assert summary_row({**SUMMARY, "max_speed_creep_mps": 3.0})["max_speed_mps"] == 3.0  # once the summary has it


def test_each_violation_on_its_own():
    ok = {"max_plate_temp_c": 249.9, "rollback_m": 0.0, "v_max_mps": 0.3, "v_desired_max_mps": 0.3,
          "stop_reason": "STOPPED_OVERHEAT", "brake_at_stop": None}
    assert violations(ok, LIMITS) == []
    assert violations({**ok, "max_plate_temp_c": 250.1}, LIMITS) == ["plate"]
    assert violations({**ok, "rollback_m": 0.2}, LIMITS) == ["rollback"]
    assert violations({**ok, "v_max_mps": 13.6}, LIMITS) == ["overspeed"]
    assert violations({**ok, "max_speed_mps": 13.6}, LIMITS) == ["overspeed"]
    assert violations({**ok, "fault_time_s": 0.5}, LIMITS) == ["fault"]
    assert violations({**ok, "stop_reason": "vehicle_stopped", "brake_at_stop": 0.0}, LIMITS) == ["standstill"]
    # the TCU holding the vehicle in an injected fault's window (FAULT on missing plant frames): its safe reaction
    assert violations({**ok, "stop_reason": "vehicle_stopped", "brake_at_stop": 0.0, "stop_in_fault_window": True},
                      LIMITS) == []
    # the driver braking (the pedal above nothing) stops creep by design
    assert violations({**ok, "stop_reason": "vehicle_stopped", "brake_at_stop": 0.052}, LIMITS) == []
    assert violations({**ok, "max_plate_temp_c": 250.1}, {**LIMITS, "plate_temp_c": 260.0}) == []


def test_the_search_objectives():
    row = {"max_plate_temp_c": 240.0, "margin_c": 10.0, "v_max_mps": 0.4, "rollback_m": 0.01}
    assert objective_value(row, "max_plate_temp_c") == 240.0 and objective_value(row, "min_margin") == -10.0
    assert objective_value({}, "overspeed") == float("-inf")


def test_fault_windows_run_from_the_fault_to_the_receive_deadline_after_it():
    """Hand values from the DBC: PLANT_OIL_TEMP every 100 ms, PLANT_SPEEDS and TCU_CMD every 10 ms, TCU_STATUS (the
    TCU's state) every 100 ms, the longest cycle 100 ms; the receive deadline is TIMEOUT_CYCLES = 3 cycles."""
    db = load_dbc()
    windows = fault_windows([parse_fault("drop:PLANT_OIL_TEMP@5-7"),
                             parse_fault("delay:PLANT_SPEEDS@10-11,delay_s=0.2"), parse_fault("flood@20-21")], db)
    assert windows == [(5.0, pytest.approx(7.0 + 0.3 + 0.01 + 0.1)),
                       (10.0, pytest.approx(11.0 + 0.2 + 0.03 + 0.01 + 0.1)), (20.0, pytest.approx(21.0 + 0.3 + 0.11))]
    assert in_windows(7.4, windows) and not in_windows(7.42, windows) and not in_windows(4.99, windows)
    assert fault_windows([parse_fault("drop:PLANT_OIL_TEMP@5-")], db)[0][1] == float("inf")


def test_fault_that_injected_faults_explain_is_no_violation():
    """FAULT is the TCU's safe reaction to missing or invalid plant frames: only FAULT time outside the fault
    windows counts (a row of an older sweep, without the column, counts all of it)."""
    ok = {"max_plate_temp_c": 249.9, "rollback_m": 0.0, "v_max_mps": 0.3, "v_desired_max_mps": 0.3}
    assert violations({**ok, "fault_time_s": 2.3, "fault_unexplained_s": 0.0}, LIMITS) == []
    assert violations({**ok, "fault_time_s": 2.3, "fault_unexplained_s": 0.02}, LIMITS) == ["fault"]
    assert violations({**ok, "fault_time_s": 2.3}, LIMITS) == ["fault"]


def test_fault_time_counts_only_outside_the_windows():
    clock = UnexplainedFault([(1.0, 2.0)])
    for k in range(31):  # 10-ms periods to 3.0 s; FAULT from 1.5 s to 2.5 s
        t = k * 0.1
        clock.update(t, "FAULT" if 1.5 <= t <= 2.5 else "CREEP")
    assert clock.seconds == pytest.approx(0.5)  # the periods ending at 2.1 ... 2.5


def test_a_run_judges_only_the_fault_time_its_faults_do_not_explain(tmp_path):
    """A real run: 1 s of PLANT_OIL_TEMP dropped puts the TCU in FAULT (it holds the vehicle) from the receive
    deadline (3 cycles of 100 ms) after the first missing frame until the frames return: all of it inside the
    fault's window, so no violation, though the summary reports the FAULT time."""
    space = tmp_path / "faulted.toml"
    space.write_text('name = "faulted"\nseed = 1\nn = 1\nduration_s = 4.0\n[inputs]\n'
                     'fault = "drop:PLANT_OIL_TEMP@1-2"\n', encoding="utf-8")
    row = run_task(load_space(space).tasks(1)[0])["row"]
    assert 0.5 <= row["fault_time_s"] <= 1.0 and row["fault_unexplained_s"] == 0.0
    assert "fault" not in row["violations"]


def test_a_pedal_pressed_while_the_vehicle_comes_to_rest_excuses_the_stop():
    """Sweep run r00197 (stop-and-go): the brake released at 125.319 s, the vehicle at rest from 125.321 s, the
    pedal at 6 % from 125.358 s: the driver stopped it. A pedal only after STOP_MIN_S (2 s) does not count."""
    text = ('name = "s"\nduration_s = 130.0\n'
            '[[driver]]\nt_s = 0.0\ncreep_request = true\nbrake = 0.0\ndesired_speed_mps = 0.3\n'
            '[[driver]]\nt_s = 125.358\ncreep_request = true\nbrake = 0.0606\ndesired_speed_mps = 0.3\n')
    scenario = parse_scenario(text, "s")
    assert pedal_while_stopping(scenario, 125.321) == 0.0606
    assert pedal_while_stopping(scenario, 123.0) == 0.0 and pedal_while_stopping(scenario, 126.0) == 0.0606


def test_a_run_outside_the_operating_range_is_never_a_silent_pass():
    """Issue 37, item 3: the summary's offending inputs become the row's ``outside_range`` and the verdict says so
    unless the run violates (then ``violation``, the column still naming them)."""
    inside = summary_row(SUMMARY)  # (the key only where there is an offending input)
    outside = summary_row({**SUMMARY, "outside_range": ["grade_rad=-0.3 (range -0.15..0.25 rad)",
                                                        "engine_speed_rpm=2100 (range 700..2000 r/min)"]})
    assert not inside.get("outside_range") and "n_outside_range" not in outside
    assert outside["outside_range"].startswith("grade_rad=-0.3") and "engine_speed_rpm=2100" in outside["outside_range"]
    assert verdict(inside, []) == "ok" and verdict(outside, []) == "outside_range"
    assert verdict(outside, ["plate"]) == verdict(inside, ["plate"]) == "violation"


def test_a_sweep_run_beyond_the_range_has_the_verdict_outside_range():
    task = load_space(SAFETY_SPACE).task(0, {
        "grade_rad": 0.29, "engine_speed_rpm": 800.0, "initial.T_clutch_c": 100.0, "initial.T_oil_c": 100.0,
        "params.vehicle.m": 7840.0, "driver.behaviour": "creep", "driver.desired_speed_mps": 0.2, "duration_s": 2.0,
        "fault": ""})
    row = run_task(task)["row"]
    assert row["verdict"] == "outside_range", row["violations"]
    assert row["outside_range"] == "grade_rad=0.29 (range -0.15..0.25 rad)"
