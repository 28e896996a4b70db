"""The parameter file: Table I as printed, every value tagged, bad files rejected with the key named."""

from __future__ import annotations

import re

import pytest

from dsg_hil.physics.params import DEFAULT_PARAMS_PATH, ParameterError, load_params, parse_params, with_overrides

# Table I of the paper (SI), copied here independently of the parameter file.
TABLE_I = {
    "vehicle.A": 3.6, "clutch.test.A_f": 0.0427, "vehicle.C_D": 0.62,
    "powertrain.C_a1": 2, "powertrain.C_a2": 0.5, "powertrain.C_a3": 0.5, "powertrain.C_in": 0.5,
    "powertrain.I_R": 18.9021, "powertrain.I_e": 3.65, "powertrain.I_m": 0.01637, "powertrain.I_in": 0.01538,
    "powertrain.I_1": 0.2102, "powertrain.I_2": 0.002373, "powertrain.I_3": 0.002373, "powertrain.I_4": 0.2034,
    "powertrain.I_40": 0.01931, "powertrain.I_50": 0.001535, "powertrain.I_5": 0.2523,
    "powertrain.K_a1": 89389, "powertrain.K_a2": 110088, "powertrain.K_a3": 65114, "powertrain.K_in": 283429,
    "clutch.test.R_i": 0.086, "clutch.test.R_o": 0.125, "vehicle.f": 0.123,
    "powertrain.i_a": 5.3585, "powertrain.i_b": 3.818, "powertrain.i_L": 1.59, "powertrain.i_H": 0.92,
    "powertrain.i_1": 0.925, "vehicle.m": 7840, "vehicle.beta": 0.174, "vehicle.delta": 1.0554,
    "vehicle.r_w": 0.1935,
}


def value(params, key):
    obj = params
    for part in key.split("."):
        obj = getattr(obj, part)
    return obj


def test_table_i_values_are_the_papers(params):
    for key, expected in TABLE_I.items():
        assert value(params, key) == pytest.approx(expected, rel=1e-12), key
        assert params.provenance[key][0] == "paper", key


def test_every_value_is_tagged_with_a_reason(params):
    assert len(params.provenance) > 90
    for key, (source, reason) in params.provenance.items():
        assert source in {"paper", "assumed", "calibrated"}
        assert len(reason) >= 5, key
    calibrated = {k for k, (s, _) in params.provenance.items() if s == "calibrated"}
    assert calibrated == {"friction.A_stribeck", "thermal.clutch.test.h_plate_oil", "clutch.CL.C_plate",
                          "clutch.CH.C_plate", "thermal.clutch.CL.Q_cool", "thermal.clutch.CH.Q_cool",
                          "powertrain.eta_L", "powertrain.eta_H", "powertrain.eta_1", "powertrain.eta_b"}


BASE = DEFAULT_PARAMS_PATH.read_text(encoding="utf-8")


def mutate(pattern: str, repl: str) -> str:
    text, n = re.subn(pattern, repl, BASE, count=1, flags=re.M)
    assert n == 1, pattern
    return text


@pytest.mark.parametrize("text, key, words", [
    (mutate(r"^K_a1 = .*\n", ""), "powertrain.K_a1", "missing"),  # the shipped file must give every key
    (mutate(r"^\[powertrain\]\n",
            "[powertrain]\nK_a9 = { value = 1.0, unit = \"1\", source = \"assumed\", why = \"xxxxxxxxxxx\" }\n"),
     "powertrain.K_a9", "unknown key"),
    (mutate(r'(^K_a1 = \{ value = 89389.0, unit = )"N\*m/rad"', r'\1"N*m"'), "powertrain.K_a1", "unit"),
    (mutate(r'(^K_a1 = \{ value = )89389.0', r'\g<1>-1.0'), "powertrain.K_a1", "out of range"),
    (mutate(r'(^K_a1 = \{ value = )89389.0', r'\g<1>"big"'), "powertrain.K_a1", "finite number"),
    (mutate(r'(^K_a1 = \{ value = 89389.0, unit = "N\*m/rad", source = )"paper"', r'\1"folklore"'),
     "powertrain.K_a1", "source"),
    (mutate(r'(^K_a1 = \{ value = 89389.0, unit = "N\*m/rad", source = "paper"), ref = "Table I"', r"\1"),
     "powertrain.K_a1", "'ref'"),
    (mutate(r'^(R_i = \{ value = )0.086', r"\g<1>0.2"), "clutch.test.R_i", "R_o"),
    (mutate(r"^Q_pump = \{ value = 3.333e-4", "Q_pump = { value = 1e-5"), "circuit.Q_pump", "smaller"),
])
def test_bad_values_name_their_key(text, key, words):
    with pytest.raises(ParameterError) as err:
        parse_params(text)
    assert key in str(err.value) and words in str(err.value)


def test_garbled_and_missing_files(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[friction\nA_stribeck = ", encoding="utf-8")
    with pytest.raises(ParameterError, match="not valid TOML"):
        load_params(bad)
    with pytest.raises(ParameterError, match="cannot read"):
        load_params(tmp_path / "absent.toml")


def test_a_complete_file_loads_as_the_shipped_one(tmp_path):
    copy = tmp_path / "full.toml"
    copy.write_text(BASE, encoding="utf-8")
    shipped, loaded = load_params(), load_params(copy)
    assert loaded == shipped and dict(loaded.provenance) == dict(shipped.provenance)


def test_a_partial_file_is_layered_on_the_shipped_one(tmp_path):
    partial = tmp_path / "partial.toml"
    partial.write_text('[meta]\nnote = "heavier"\n[vehicle]\nm = { value = 9000.0, unit = "kg", source = '
                       '"assumed", why = "a loaded bus" }\n[clutch.CL]\nN = { value = 8, unit = "1", source = '
                       '"assumed", why = "one more plate" }\n', encoding="utf-8")
    shipped, params = load_params(), load_params(partial)
    assert params.vehicle.m == 9000.0 and params.clutch.CL.N == 8.0
    assert params.provenance["vehicle.m"] == ("assumed", "a loaded bus")
    assert params.vehicle.f == shipped.vehicle.f and params.clutch.CL.R_o == shipped.clutch.CL.R_o
    assert params.friction == shipped.friction
    assert params.provenance["vehicle.f"] == shipped.provenance["vehicle.f"]
    assert list(params.provenance) == list(shipped.provenance)  # every key, in the shipped order


@pytest.mark.parametrize("text, words", [
    ('[vehicle]\nmass = { value = 1.0, unit = "kg", source = "assumed", why = "xxxxx" }\n', "vehicle.mass: unknown"),
    ('[vehicle]\nm = { value = 9000.0, unit = "kg" }\n', "vehicle.m: source"),
    ('[vehicle]\nm = { value = 9000.0, unit = "t", source = "assumed", why = "xxxxx" }\n', "vehicle.m: unit"),
    ('[clutch.test]\nR_i = { value = 0.2, unit = "m", source = "assumed", why = "xxxxx" }\n', "R_o"),
    ("vehicle = 3\n", "vehicle: expected a table"),
])
def test_a_partial_file_is_checked_key_by_key(tmp_path, text, words):
    partial = tmp_path / "partial.toml"
    partial.write_text(text, encoding="utf-8")
    with pytest.raises(ParameterError, match=re.escape(words)):
        load_params(partial)


def test_overrides_are_checked_and_tagged(params):
    heavy = with_overrides(params, {"vehicle.m": 9000, "clutch.CL.N": "8 1", "engine.M_max": "300[N*m]"}, "test")
    assert (heavy.vehicle.m, heavy.clutch.CL.N, heavy.engine.M_max) == (9000.0, 8.0, 300.0)
    assert heavy.provenance["vehicle.m"] == ("override", "test vehicle.m=9000 (was 7840, paper)")
    assert heavy.provenance["vehicle.f"] == params.provenance["vehicle.f"]
    assert params.vehicle.m == 7840.0 and params.provenance["vehicle.m"][0] == "paper"  # the original unchanged
    for overrides, words in [({"vehicle.m": 0.0}, "out of range"), ({"vehicle.m": float("inf")}, "finite"),
                             ({"vehicle.m": True}, "finite"), ({"clutch.CL.N": 6.5}, "whole number"),
                             ({"vehicle.m": "9 t"}, "unit must be 'kg'"), ({"vehicle.x": 1.0}, "no parameter"),
                             ({"clutch.CL": 1.0}, "no parameter"), ({"engine.omega_rated": 50.0}, "omega_idle")]:
        with pytest.raises(ParameterError, match=words):
            with_overrides(params, overrides, "test")
