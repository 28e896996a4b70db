from __future__ import annotations

import pytest

from dsg_hil.sim.scenario import ScenarioError, load_scenario, parse_scenario


def test_default_scenario_ships_and_plays_driver_events():
    s = load_scenario()
    assert s.duration_s > 174 and s.T_CL_c == s.T_CH_c == 100.0  # Section V.B starts both clutches at 100 degC
    assert not s.driver_at(0.5).creep_request and s.driver_at(0.5).brake == 1.0
    assert s.driver_at(1.0).creep_request and s.driver_at(100.0).desired_speed_mps > 0.0


def test_driver_events_apply_at_the_plants_time_exactly():
    """An event at t_s (a decimal in the file) applies from the step whose time it is: the plant's time k dt_ns / 1e9
    is that decimal's float, compared with no tolerance (a float sum of dt, below it for some k, would apply it a
    step late)."""
    summed, late = 0.0, []
    for k in range(1, 2000):
        summed += 1e-3
        if summed < k / 1000:
            late.append(k)
    assert late
    for k in late[:20]:
        s = parse_scenario(f"duration_s = 10\n[[driver]]\nt_s = 0\n[[driver]]\nt_s = {k / 1000!r}\nbrake = 1\n")
        assert s.driver_at(k * 1_000_000 / 1e9).brake == 1.0 and s.driver_at((k - 1) * 1_000_000 / 1e9).brake == 0.0


@pytest.mark.parametrize("text, key", [
    ("duration_s = 10\n", "driver"),
    ("duration_s = -1\n[[driver]]\nt_s = 0\n", "duration_s"),
    ("duration_s = 10\n[[driver]]\nt_s = 0\nbrake = 3\n", "driver[0].brake"),
    ("duration_s = 10\n[[driver]]\nt_s = 0\nwiper = 1\n", "driver[0].wiper"),
    ("duration_s = 10\nfoo = 1\n[[driver]]\nt_s = 0\n", "foo"),
    ("duration_s = 10\n[[driver]]\nt_s = 5\n[[driver]]\nt_s = 1\n", "time order"),
    ("duration_s = 10\n[initial]\nT_oil_c = 'hot'\n[[driver]]\nt_s = 0\n", "initial.T_oil_c"),
    ("duration_s = [", "not valid TOML"),
    ("duration_s = 10\n[initial]\nT_CH_c = 400\n[[driver]]\nt_s = 0\n", "initial.T_CH_c"),
    ("duration_s = 10\n[initial]\nT_CL_c = 'warm'\n[[driver]]\nt_s = 0\n", "initial.T_CL_c"),
    ("duration_s = 10\n[initial]\nT_plate_c = 90\n[[driver]]\nt_s = 0\n", "initial.T_plate_c: unknown key"),
])
def test_bad_scenarios_name_the_key(text, key):
    with pytest.raises(ScenarioError, match=key.replace("[", r"\[").replace("]", r"\]")):
        parse_scenario(text)


def test_per_clutch_start_temperatures_default_to_the_common_one():
    base = "duration_s = 10\n[initial]\nT_clutch_c = 120\nT_oil_c = 80\n{extra}[[driver]]\nt_s = 0\n"
    s = parse_scenario(base.format(extra=""))
    assert (s.T_CL_c, s.T_CH_c) == (120.0, 120.0)
    s = parse_scenario(base.format(extra="T_CH_c = 60\n"))
    assert (s.T_CL_c, s.T_CH_c) == (120.0, 60.0)
    T = s.initial_temperatures(("Fo", "CL", "CLo", "CH"))
    assert T == {"Fo": 80.0, "CL": 120.0, "CLo": 80.0, "CH": 60.0}
    assert s.with_duration(5.0).T_CH_c == 60.0
