"""The documented operating range, written once (dsg_hil.sim.operating_range) and checked by every run: a run
outside it still runs, and its summary names each offending input (issue 37, item 3)."""

from __future__ import annotations

from dsg_hil.physics.params import load_params, with_overrides
from dsg_hil.results.outcome import Summary
from dsg_hil.sim.operating_range import OPERATING_RANGE, outside_range
from dsg_hil.sim.run import RunConfig, open_run
from dsg_hil.sim.scenario import load_scenario, parse_scenario


def scenario(grade=0.174, idle=800.0, T_clutch=100.0, T_oil=100.0, speed=0.206, duration=10.0):
    return parse_scenario(
        f'duration_s = {duration}\ngrade_rad = {grade}\nengine_speed_rpm = {idle}\n'
        f"[initial]\nT_clutch_c = {T_clutch}\nT_oil_c = {T_oil}\n"
        "[[driver]]\nt_s = 0.0\nbrake = 1.0\n"
        f"[[driver]]\nt_s = 1.0\ncreep_request = true\ndesired_speed_mps = {speed}\n", "range")


def test_the_default_scenario_and_the_ranges_ends_are_inside():
    params = load_params()
    assert outside_range(load_scenario(), params) == []
    r = OPERATING_RANGE
    for end in (0, 1):
        pick = (lambda b: b.lo) if end == 0 else (lambda b: b.hi)
        inside = scenario(pick(r["grade_rad"]), pick(r["engine_speed_rpm"]), pick(r["initial.T_CL_c"]),
                          pick(r["initial.T_oil_c"]), pick(r["driver.desired_speed_mps"]))
        assert outside_range(inside, with_overrides(params, {"vehicle.m": pick(r["params.vehicle.m"])})) == []


def test_each_input_beyond_its_range_is_named_once():
    params = load_params()
    assert outside_range(scenario(grade=-0.3), params) == ["grade_rad=-0.3 (range -0.15..0.25 rad)"]
    assert [s.split("=")[0] for s in outside_range(scenario(idle=2100.0, T_clutch=160.0, T_oil=30.0, speed=0.5),
                                                   params)] == [
        "initial.T_CL_c", "initial.T_CH_c", "initial.T_oil_c", "engine_speed_rpm", "driver.desired_speed_mps"]
    heavy = with_overrides(params, {"vehicle.m": 12544.0})
    assert outside_range(scenario(), heavy) == ["params.vehicle.m=12544 (range 3920..11760 kg)"]
    # desired speed 0 with creep requested asks the TCU to hold the vehicle: in range (issue 37, item 4)
    assert outside_range(scenario(speed=0.0), params) == []


def test_a_run_outside_the_range_still_runs_and_its_summary_says_so():
    with open_run(RunConfig(scenario=scenario(grade=-0.3, duration=1.5))) as run:
        summary = run.run()
    assert summary.sim_time_s == 1.5 and summary["outside_range"] == ["grade_rad=-0.3 (range -0.15..0.25 rad)"]
    with open_run(RunConfig(scenario=scenario(duration=0.5))) as run:
        inside = run.run()
    assert inside.outside_range == () and "outside_range" not in inside.as_json()
    assert Summary.from_json(summary.as_json()).outside_range == summary.outside_range  # read back (a sweep's)
