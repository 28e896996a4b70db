"""The space file: checked at load (exit 2, one line naming the key, nothing written); the same seed gives the same
runs; the driver behaviours give valid scenarios."""

from __future__ import annotations

from pathlib import Path

import pytest

from dsg_hil.cli import main
from dsg_hil.sim.scenario import parse_scenario
from dsg_hil.sweep.drivers import BEHAVIOURS, driver_events
from dsg_hil.physics.params import load_params
from dsg_hil.protocol.faults import parse_fault
from dsg_hil.sim.operating_range import OPERATING_RANGE
from dsg_hil.sweep.space import SAFETY_SPACE, load_space, parse_space

from .conftest import SMALL

BAD = [
    ("sampler = 'grid'\n", "sampler: 'grid' is not one of lhs, sobol"),
    ("colour = 1\n", "colour: unknown key"),
    ("[inputs]\ngrade_rad = {uniform = [0.3, 0.1]}\n", "inputs.grade_rad.uniform: low 0.3 above high 0.1"),
    ("[inputs]\ngrade_rad = {uniform = [0.0, 0.9]}\n", "inputs.grade_rad = 0.9: grade_rad: 0.9 is out of range"),
    ("[inputs]\ngrade = {uniform = [0.0, 0.1]}\n", "inputs.grade: unknown input"),
    ("[inputs]\n'params.vehicle.mass' = {uniform = [1, 2]}\n", "no parameter 'vehicle.mass'"),
    ("[inputs]\n'params.vehicle.m' = {uniform = [-5, 2]}\n", "inputs.params.vehicle.m = -5.0"),
    ("[inputs]\n'driver.behaviour' = {choice = ['dance']}\n", "inputs.driver.behaviour: behaviours are"),
    ("[inputs]\n'driver.speed' = 1.0\n", "inputs.driver.speed: unknown driver setting"),
    ("[inputs]\n'driver.creep_s' = 0.0\n'driver.behaviour' = 'stop_and_go'\n", "inputs.driver.creep_s: must be"),
    ("[inputs]\nfault = {choice = ['', 'explode:TCU_CMD']}\n", "inputs.fault"),
    ("[inputs]\nfault = 'drop:NOPE@1-2'\n", "inputs.fault: --fault 'drop:NOPE@1-2': message 'NOPE' is not in the DBC"),
    ("[inputs]\nfault = {choice = ['stuck:PLANT_VEHICLE.Nope,value=0']}\n",
     "signal 'PLANT_VEHICLE.Nope' is not in the DBC"),
    ("[inputs]\ngrade_rad = {normal = [0.1, 0.0]}\n", "inputs.grade_rad.normal: the standard deviation"),
    ("[controller]\nkind = 'fpga'\n", "controller.kind: 'fpga' is not one of"),
    ("[controller]\nkind = 'python'\n", "controller.target: 'module:factory' expected"),
    ("[limits]\nplate = 250\n", "limits.plate: unknown limit"),
    ("[search]\nobjective = 'fun'\n", "search.objective: 'fun' is not one of"),
    ("n = -1\n", "n: must be a whole number >= 0"),
    ("scenario = 'missing.toml'\n", "missing.toml: cannot read scenario"),
    ("[inputs\n", "not valid TOML"),
    ("[inputs]\nfault_at_s = {uniform = [-1.0, 5.0]}\n", "inputs.fault_at_s: must be seconds >= 0"),
]


@pytest.mark.parametrize(("text", "message"), BAD, ids=[m for _, m in BAD])
def test_a_bad_space_file_exits_2_with_one_line_naming_the_key_and_writes_nothing(tmp_path, capsys, text, message):
    space = tmp_path / "bad.toml"
    space.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["sweep", str(space), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: ") and message in err, err
    assert str(space) in err
    assert not out.exists()


def test_a_space_file_that_is_not_there(tmp_path, capsys):
    assert main(["sweep", str(tmp_path / "none.toml"), "--out", str(tmp_path / "out")]) == 2
    assert "none.toml: cannot read sweep space" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_same_seed_gives_the_same_runs_another_seed_others(small_space: Path):
    first, again = load_space(small_space).tasks(), load_space(small_space).tasks()
    assert first == again and len(first) == 12
    other = parse_space(SMALL.replace("seed = 7", "seed = 8")).tasks()
    assert [t["run_id"] for t in other] != [t["run_id"] for t in first]
    grades = [t["inputs"]["grade_rad"] for t in first]
    assert all(0.0 <= g <= 0.2 for g in grades)
    # a Latin hypercube: one sample in each twelfth of the range
    assert sorted(int(g / 0.2 * 12) for g in grades) == list(range(12))
    sobol = parse_space(SMALL.replace('seed = 7', 'seed = 7\nsampler = "sobol"')).tasks()
    assert sobol != first and sobol == parse_space(SMALL.replace('seed = 7', 'seed = 7\nsampler = "sobol"')).tasks()


def test_a_task_is_plain_data_with_a_valid_scenario_and_parameters(small_space: Path):
    task = load_space(small_space).tasks(1)[0]
    scenario = parse_scenario(task["scenario"])
    assert scenario.duration_s == 3.0 and scenario.grade_rad == pytest.approx(task["inputs"]["grade_rad"])
    assert set(task["params"]) == {"vehicle.m"} and 6000 <= task["params"]["vehicle.m"] <= 9000
    assert scenario.T_CL_c == pytest.approx(task["inputs"]["initial.T_clutch_c"])


def test_set_fixes_a_parameter_in_every_run_and_refuses_one_the_space_draws(small_space: Path, tmp_path, capsys):
    space = load_space(small_space)
    fixed = space.with_parameters({"vehicle.f": 0.1}).tasks()
    assert [t["params"] for t in fixed] == [{**t["params"], "vehicle.f": 0.1} for t in space.tasks()]
    assert [t["inputs"]["grade_rad"] for t in fixed] == [t["inputs"]["grade_rad"] for t in space.tasks()]
    out = tmp_path / "out"
    for option, message in [("vehicle.m=9000", f"--set vehicle.m: {small_space} draws params.vehicle.m"),
                            ("vehicle.f=-5", "--set vehicle.f: -5.0 is out of range"),
                            ("vehicle.nosuch=1", "--set: no parameter 'vehicle.nosuch'")]:
        assert main(["sweep", str(small_space), "--set", option, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err.startswith("error: ") and message in err, err
        assert not out.exists()


@pytest.mark.parametrize("behaviour", BEHAVIOURS)
def test_each_driver_behaviour_gives_a_valid_scenario(behaviour):
    events = driver_events({"behaviour": behaviour, "creep_s": 3.0, "stop_s": 2.0, "toggle_s": 4.0,
                            "change_s": 5.0, "stop_at_s": 10.0, "pause_s": 3.0}, 20.0)
    text = 'duration_s = 20.0\n' + "".join(
        "[[driver]]\n" + "".join(f"{k} = {str(v).lower()}\n" for k, v in e.items()) for e in events)
    scenario = parse_scenario(text)
    assert scenario.driver_at(0.5).brake == 1.0 and not scenario.driver_at(0.5).creep_request
    assert scenario.driver_at(1.5).creep_request
    if behaviour in ("stop_and_go", "creep_toggles", "overheat_restart"):
        assert any(not scenario.driver_at(t).creep_request for t in (5.0, 8.0, 12.0))
        assert any(scenario.driver_at(t).creep_request for t in (13.0, 14.5, 17.0, 19.5))  # and creep again
    if behaviour == "speed_changes":
        assert {scenario.driver_at(t).desired_speed_mps for t in (2.0, 7.0)} == {0.206, 0.1}


def test_brake_drag_holds_the_pedal_lightly_in_its_window_with_creep_requested():
    events = driver_events({"behaviour": "brake_drag", "drag_level": 0.047, "drag_onset_s": 5.0,
                            "drag_duration_s": 2.5}, 20.0)
    text = 'duration_s = 20.0\n' + "".join(
        "[[driver]]\n" + "".join(f"{k} = {str(v).lower()}\n" for k, v in e.items()) for e in events)
    scenario = parse_scenario(text)
    assert [scenario.driver_at(t).brake for t in (4.9, 5.0, 7.4, 7.5)] == [0.0, 0.047, 0.047, 0.0]
    assert all(scenario.driver_at(t).creep_request for t in (4.9, 5.0, 7.4, 7.5))


FAULTS = SMALL + """fault = {choice = ["", "drop:PLANT_OIL_TEMP", "stuck:PLANT_VEHICLE.VehicleSpeed,value=0",
                             "drop:TCU_CMD@1-2"]}
fault_at_s = {uniform = [0.5, 2.0]}
"""


def test_a_fault_without_a_window_gets_the_drawn_one_in_the_fault_syntax():
    tasks = parse_space(FAULTS).tasks(40)
    assert any(not t["faults"] for t in tasks)  # some runs without a fault
    for task in tasks:
        fault = task["inputs"]["fault"]
        if not fault:
            continue
        (text,) = task["faults"]
        spec = parse_fault(text)  # what dsg-hil run --fault reads
        if "@" in fault:  # a window given in the file is kept
            assert text == fault
            continue
        assert spec.start_s == pytest.approx(task["inputs"]["fault_at_s"], abs=1e-3)
        assert spec.end_s == float("inf")  # no fault_duration_s: to the end of the run
    timed = parse_space(FAULTS + "fault_duration_s = 0.25\n").tasks(40)
    windows = [parse_fault(t["faults"][0]) for t in timed if t["faults"] and "@" not in t["inputs"]["fault"]]
    assert windows and all(w.end_s == pytest.approx(w.start_s + 0.25, abs=2e-3) for w in windows)
    assert any("value=0" in t["faults"][0] for t in timed if t["faults"])  # options kept after the window


def test_the_shipped_safety_space_covers_the_range_and_behaviours_of_issue_18():
    """The operating range (grades -0.15...0.25 rad, mass +-50 %, plates and oil 40-150 degC, idle 700-2000 r/min,
    desired speed 0.05-0.4 m/s: dsg_hil.sim.operating_range) and its margin beyond each end (issue 37), brake drag
    0-10 % with any onset and duration, every driver behaviour, frame faults (some runs with none)."""
    space = load_space(SAFETY_SPACE)
    duration = float(space.base["duration_s"])
    m = load_params().vehicle.m

    def covers(key: str, lo: float, hi: float) -> bool:
        dist = space.inputs[key]
        return dist.kind == "uniform" and dist.args[0] <= lo + 1e-9 and dist.args[1] >= hi - 1e-9  # (0.4 + 0.025)

    drawn_as = {"initial.T_CL_c": "initial.T_clutch_c", "initial.T_CH_c": "initial.T_clutch_c"}
    for name, bound in OPERATING_RANGE.items():
        assert covers(drawn_as.get(name, name), bound.lo - bound.margin, bound.hi + bound.margin), name
    assert covers("driver.speed_2_mps", *space.inputs["driver.desired_speed_mps"].args)
    assert covers("params.vehicle.m", 0.5 * m, 1.5 * m)
    assert covers("driver.drag_level", 0.0, 0.1) and covers("driver.drag_onset_s", 0.0, duration - 10.0)
    assert space.inputs["driver.drag_duration_s"].args[1] >= duration
    assert set(space.inputs["driver.behaviour"].args) == set(BEHAVIOURS)
    tasks = space.tasks(200)
    for task in tasks:
        scenario = parse_scenario(task["scenario"])
        for text in task["faults"]:
            assert 0.0 <= parse_fault(text).start_s < duration
    with_fault = [t for t in tasks if t["inputs"]["fault"]]  # frame faults (the latent ones: test_latent.py)
    assert 0.3 * len(tasks) < len(with_fault) < 0.7 * len(tasks)
    assert {parse_fault(t["faults"][0]).kind for t in with_fault} >= {"drop", "delay", "corrupt_crc", "stuck"}
    assert min(t["inputs"]["grade_rad"] for t in tasks) < -0.1  # downhill drawn
    dragged = [t for t in tasks if t["inputs"]["driver.drag_level"] > 0.04]
    assert any(t["inputs"]["driver.behaviour"] != "brake_drag" for t in dragged)  # drag with any behaviour
    assert scenario.duration_s == duration
