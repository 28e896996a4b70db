from __future__ import annotations

import pytest

from dsg_hil.scenario import ScenarioError, load_scenario, parse_scenario


def test_default_scenario_ships_and_plays_driver_events():
    s = load_scenario()
    assert s.duration_s > 100 and s.T_clutch_c == 100.0  # Section V.B starts both clutches at 100 degC
    assert not s.driver_at(0.5).creep_request and s.driver_at(0.5).brake == 1.0
    assert s.driver_at(1.0).creep_request and s.driver_at(100.0).desired_speed_mps > 0.0


@pytest.mark.parametrize("text, key", [
    ("duration_s = 10\n", "driver"),
    ("duration_s = -1\n[[driver]]\nt_s = 0\n", "duration_s"),
    ("duration_s = 10\n[[driver]]\nt_s = 0\nbrake = 3\n", "driver[0].brake"),
    ("duration_s = 10\n[[driver]]\nt_s = 0\nwiper = 1\n", "driver[0].wiper"),
    ("duration_s = 10\nfoo = 1\n[[driver]]\nt_s = 0\n", "foo"),
    ("duration_s = 10\n[[driver]]\nt_s = 5\n[[driver]]\nt_s = 1\n", "time order"),
    ("duration_s = 10\n[initial]\nT_oil_c = 'hot'\n[[driver]]\nt_s = 0\n", "initial.T_oil_c"),
    ("duration_s = [", "not valid TOML"),
])
def test_bad_scenarios_name_the_key(text, key):
    with pytest.raises(ScenarioError, match=key.replace("[", r"\[").replace("]", r"\]")):
        parse_scenario(text)
