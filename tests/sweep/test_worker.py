"""A sweep's runs keep their warnings off the terminal (counted in each summary, kept in the logs): in the page's
re-run of the worst run (:func:`dsg_hil.sweep.worker.runs_quiet`) and for good in a Dask worker."""

from __future__ import annotations

import logging

import pytest

from dsg_hil.sweep.worker import RUN_LOGGERS, runs_quiet


def test_runs_quiet_silences_the_runs_warnings_and_restores_them():
    runner, tcu = logging.getLogger("dsg_hil.sim.runner"), logging.getLogger("ecu_stub.runner")
    assert {"dsg_hil", "ecu_stub"} == set(RUN_LOGGERS)
    before = [logging.getLogger(n).level for n in RUN_LOGGERS]
    assert runner.isEnabledFor(logging.WARNING) and tcu.isEnabledFor(logging.WARNING)
    with runs_quiet():
        assert not runner.isEnabledFor(logging.WARNING) and not tcu.isEnabledFor(logging.WARNING)
        assert runner.isEnabledFor(logging.ERROR)  # errors still reach the terminal
    assert [logging.getLogger(n).level for n in RUN_LOGGERS] == before
    assert runner.isEnabledFor(logging.WARNING)


@pytest.mark.slow
def test_a_stop_held_by_the_tcu_in_a_fault_window_is_its_safe_reaction_not_a_standstill():
    """A 1,000-run sample of the shipped space (r00142): PLANT_SPEEDS dropped for 4.5 s while creeping downhill; the
    TCU went to FAULT and braked the vehicle to rest 0.1 s into the fault, which the verdict called a standstill
    while creep was requested. It is the safe reaction the fault window explains (judged by roll-back and speed)."""
    from dsg_hil.sweep.space import SAFETY_SPACE, load_space
    from dsg_hil.sweep.worker import run_task

    inputs = {"grade_rad": -0.0705, "engine_speed_rpm": 1939.0, "initial.T_clutch_c": 95.7, "initial.T_oil_c": 58.0,
              "params.vehicle.m": 5668.0, "driver.behaviour": "creep_toggles", "driver.desired_speed_mps": 0.3414,
              "driver.toggle_s": 18.52, "driver.toggle_brake": True, "duration_s": 100.0,
              "fault": "drop:PLANT_SPEEDS", "fault_at_s": 91.404, "fault_duration_s": 4.513}
    row = run_task(load_space(SAFETY_SPACE).task(0, inputs))["row"]
    assert row["stop_reason"] == "vehicle_stopped" and row["brake_at_stop"] == 0.0  # before: a "standstill"
    assert row["stop_in_fault_window"] is True and row["verdict"] == "ok", row["violations"]
