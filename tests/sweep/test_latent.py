"""Latent sensor faults in a sweep space (dsg_hil.sweep.latent): what is drawn, that it is deterministic, that the
drawn faults are faults the DBC takes and a run injects, and that their sizes come from the TCU's own constants."""

from __future__ import annotations

import dataclasses

import pytest

from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.faults import FaultInjector, check_against_dbc, parse_fault
from dsg_hil.sim.operating_range import OPERATING_RANGE
from dsg_hil.sweep.latent import LATENT_SIGNALS, latent_faults, multiple, thresholds
from dsg_hil.sweep.space import SAFETY_SPACE, SpaceError, load_space, parse_space
from dsg_hil.sweep.verdict import latent_class, latent_counts
from ecu_stub import plausibility, sensor_checks
from ecu_stub.calibration import load_calibration

SPACE = 'seed = 3\nduration_s = 100.0\n[inputs]\ngrade_rad = {uniform = [0.0, 0.1]}\n'


def drawn(space, n):
    return [latent_faults(values["latent"]) for values in space.samples(n)]


def test_the_shipped_space_draws_offsets_and_gains_on_every_input_both_signs_below_and_beyond_thresholds():
    space = load_space(SAFETY_SPACE)
    assert space.latent is not None
    duration = float(space.base["duration_s"])
    runs = drawn(space, 400)
    assert {len(faults) for faults in runs} == {0, 1, 2}
    faults = [parse_fault(f) for run in runs for f in run]
    assert all(len({parse_fault(f).target for f in run}) == len(run) for run in runs)  # two at once: two signals
    assert {f.target for f in faults} == set(LATENT_SIGNALS)
    assert {f.kind for f in faults} == {"offset", "gain"} and all(f.end_s == float("inf") for f in faults)
    signs = {(f.kind, f.value > (0.0 if f.kind == "offset" else 1.0)) for f in faults}
    assert signs == {("offset", True), ("offset", False), ("gain", True), ("gain", False)}
    multiples = [multiple(f.as_option()) for f in faults]
    assert min(multiples) >= 0.1 - 1e-3 and max(multiples) <= 2.5 + 1e-3
    assert sum(x < 1.0 for x in multiples) > 0.25 * len(multiples) and sum(x > 1.0 for x in multiples) > 0.5 * len(
        multiples)  # (uniform over 0.1-2.5: 37.5 % below, 62.5 % beyond)
    at_zero = [f for f in faults if f.start_s == 0.0]
    assert 0.15 * len(faults) < len(at_zero) < 0.35 * len(faults)
    later = [f.start_s for f in faults if f.start_s > 0.0]
    assert max(later) < duration and min(later) < 0.1 * duration and max(later) > 0.9 * duration


def test_the_draw_is_a_function_of_the_seed_and_the_run_index():
    text = SPACE + "[latent]\n"
    space = parse_space(text)
    first = [values["latent"] for values in space.samples(30)]
    assert first == [values["latent"] for values in parse_space(text).samples(30)]
    assert first[:10] == [values["latent"] for values in space.samples(10)]  # whatever the n (not stratified)
    other = [values["latent"] for values in parse_space(text.replace("seed = 3", "seed = 4")).samples(30)]
    assert other != first
    assert [values["grade_rad"] for values in space.samples(30)] == \
        [values["grade_rad"] for values in parse_space(SPACE).samples(30)]  # the sampler's draws unchanged
    assert space.digest != parse_space(SPACE).digest  # (a resumed sweep tells the two apart)
    tasks = space.tasks(30)
    assert all(task["faults"] == latent_faults(task["inputs"]["latent"]) for task in tasks)  # no frame fault here


def test_every_drawn_fault_is_one_the_dbc_takes_and_the_injector_builds():
    db = load_dbc()
    faults = [f for run in drawn(load_space(SAFETY_SPACE), 200) for f in run]
    specs = [parse_fault(f) for f in faults]
    for spec in specs:
        check_against_dbc(spec, db)
    FaultInjector(db, specs)
    assert faults[0].startswith(("offset:", "gain:")) and "@" in faults[0] and ",value=" in faults[0]


def test_the_thresholds_are_the_tcus_constants_not_copies(monkeypatch):
    cal = load_calibration()
    limits = thresholds()
    idle, v_top = OPERATING_RANGE["engine_speed_rpm"].lo, OPERATING_RANGE["driver.desired_speed_mps"].hi
    shaft = idle / cal.vehicle.input_ratio
    assert limits["PLANT_OIL_TEMP.T_OilCL"].offset == sensor_checks.OIL_TOL_K
    assert limits["PLANT_SPEEDS.ClutchInputSpeed"].offset == pytest.approx(
        sensor_checks.N_ABS_RPM + sensor_checks.N_REL * shaft)
    assert limits["PLANT_ENGINE.EngineSpeed"].offset == pytest.approx(
        cal.vehicle.input_ratio * limits["PLANT_SPEEDS.ClutchInputSpeed"].offset)
    assert limits["PLANT_PRESSURE.P_CL"].offset == pytest.approx(
        sensor_checks.P_ABS_MPA + sensor_checks.P_REL * cal.speed.P_max_mpa / 2)
    assert limits["PLANT_VEHICLE.VehicleSpeed"].offset == pytest.approx(
        plausibility.REL_TOL * v_top + plausibility.DISTANCE_M / plausibility.HEAL_S)
    assert limits["PLANT_SPEEDS.CHOutputSpeed"].offset * cal.CH.speed_ratio_m == pytest.approx(
        limits["PLANT_VEHICLE.VehicleSpeed"].offset * 30 / 3.141592653589793)
    # the TCU's constants changed: the thresholds follow them
    monkeypatch.setattr(sensor_checks, "OIL_TOL_K", 2 * sensor_checks.OIL_TOL_K)
    monkeypatch.setattr(sensor_checks, "N_ABS_RPM", sensor_checks.N_ABS_RPM + 10.0)
    monkeypatch.setattr(sensor_checks, "P_REL", 2 * sensor_checks.P_REL)
    monkeypatch.setattr(plausibility, "REL_TOL", 2 * plausibility.REL_TOL)
    changed = thresholds(dataclasses.replace(cal, vehicle=dataclasses.replace(cal.vehicle, input_ratio=4.0)))
    assert changed["PLANT_OIL_TEMP.T_OilCH"].offset == 2 * limits["PLANT_OIL_TEMP.T_OilCH"].offset
    assert changed["PLANT_SPEEDS.ClutchInputSpeed"].offset == pytest.approx(
        sensor_checks.N_ABS_RPM + sensor_checks.N_REL * idle / 4.0)
    assert changed["PLANT_ENGINE.EngineSpeed"].offset == pytest.approx(
        4.0 * changed["PLANT_SPEEDS.ClutchInputSpeed"].offset)
    assert changed["PLANT_PRESSURE.P_CH"].offset > limits["PLANT_PRESSURE.P_CH"].offset
    assert changed["PLANT_VEHICLE.VehicleSpeed"].offset > limits["PLANT_VEHICLE.VehicleSpeed"].offset


def test_a_multiple_is_the_error_over_the_threshold():
    limits = thresholds()
    oil, speed = limits["PLANT_OIL_TEMP.T_OilCL"], limits["PLANT_SPEEDS.ClutchInputSpeed"]
    assert multiple(f"offset:PLANT_OIL_TEMP.T_OilCL@0-,value={-1.5 * oil.offset}") == pytest.approx(1.5)
    assert multiple(f"gain:PLANT_SPEEDS.ClutchInputSpeed@3-,value={1 - 0.5 * speed.gain}") == pytest.approx(0.5)


@pytest.mark.parametrize("section, words", [
    ("colour = 1", "latent.colour: unknown key"),
    ("scale = [2.5, 0.1]", "latent.scale: low 2.5 above high 0.1"),
    ("scale = [0.0, 1.0]", "latent.scale: must be > 0"),
    ("scale = [1.0, 1e9]", "latent.scale: 1e+09 times PLANT_OIL_TEMP.T_OilCL's threshold: offset value -1e+10 degC "
                           "cannot be encoded"),  # no DBC signal carries such an offset
    ("per_run = [0, 3]", "latent.per_run: must lie within 0-2"),
    ("per_run = [0.5, 1]", "latent.per_run: must be [low, high], two whole numbers"),
    ("at_zero = 1.5", "latent.at_zero: must be a share within [0, 1]"),
    ("kinds = [\"stuck\"]", "latent.kinds: 'stuck' is not one of offset, gain"),
    ("signals = [\"PLANT_OIL_TEMP.T_Oil\"]", "latent.signals: 'PLANT_OIL_TEMP.T_Oil' is not one of"),
    ("signals = [\"PLANT_PRESSURE.P_CL\"]", "latent.per_run: 2 faults per run on distinct signals"),
])
def test_a_bad_latent_section_names_the_file_and_key(section, words):
    with pytest.raises(SpaceError) as info:
        parse_space(SPACE + "[latent]\n" + section + "\n", "space.toml")
    assert str(info.value).startswith(f"space.toml: {words}"), str(info.value)


def test_the_verdict_counts_violating_runs_by_their_latent_faults():
    rows = [{"latent_x": 1.6}, {"latent_x": 0.4}, {"latent_x": None}, {}, {"latent_x": float("nan")}]
    assert [latent_class(r) for r in rows] == ["beyond", "within", "none", "none", "none"]
    assert latent_counts(rows) == ("1 with a latent fault beyond its detection threshold, 1 with latent faults all "
                                   "within their thresholds, 3 without a latent fault")
    assert latent_counts(rows[2:]) == ""  # a space without latent faults: nothing said


# a 2-s creep of the safety space's inputs, without a frame fault
SHORT_CREEP = {"grade_rad": 0.1, "engine_speed_rpm": 800.0, "initial.T_clutch_c": 100.0, "initial.T_oil_c": 100.0,
               "params.vehicle.m": 7840.0, "driver.behaviour": "creep", "driver.desired_speed_mps": 0.2,
               "duration_s": 2.0, "fault": ""}


def one_early_latent_fault(space, inputs) -> tuple[int, dict, str]:
    """The first sample index at which ``space`` draws one latent fault for ``inputs`` beginning before 1.5 s, the
    values with it, and its ``--fault`` string."""
    index, values = next((i, v) for i in range(100) if len(latent_faults((v := space.with_latent(i, inputs))["latent"]))
                         == 1 and parse_fault(v["latent"]).start_s < 1.5)
    (text,) = latent_faults(values["latent"])
    return index, values, text


def test_a_run_with_a_drawn_latent_fault_injects_it():
    from dsg_hil.sweep.worker import run_task

    space = load_space(SAFETY_SPACE)
    index, values, text = one_early_latent_fault(space, SHORT_CREEP)
    task = space.task(index, values)
    assert task["faults"] == [text]
    result = run_task(task)
    row, summary = result["row"], result["summary"]
    assert row["in.latent"] == text and row["latent_x"] == pytest.approx(multiple(text))
    assert summary["faults"]["injected"].get(parse_fault(text).describe(), 0) > 0, summary["faults"]
