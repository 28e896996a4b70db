"""The TCU calibration file: the shipped one loads and says how each value was obtained; bad files fail naming
the key."""

from __future__ import annotations

import tomllib

import pytest

from ecu_stub.calibration import DEFAULT_CALIBRATION, CalibrationError, dump_calibration, load_calibration, \
    parse_calibration, raw_sections
from ecu_stub.cli import main

TEXT = DEFAULT_CALIBRATION.read_text(encoding="utf-8")


def test_shipped_calibration_loads_and_every_value_says_how_it_was_obtained():
    cal = load_calibration()
    assert cal.strategy.T_safe_c == 250.0 and cal.CL.k_geom_m3 > 0 and cal.CH.speed_ratio_m > cal.CL.speed_ratio_m
    data = tomllib.loads(TEXT)
    sections = [data[s] for s in ("strategy", "speed", "launch", "vehicle", "friction")] + list(data["clutch"].values())
    for section in sections:
        for entry in section.values():
            assert entry["source"] in ("identified", "derived", "chosen") and entry["how"].strip()


def test_dump_round_trips():
    assert parse_calibration(dump_calibration(raw_sections(), "header")) == load_calibration()


@pytest.mark.parametrize("old, new, key", [
    ("kp_n_per_mps = { value = ", "kp_n_per_mps = { value = -", "speed.kp_n_per_mps"),
    ('unit = "N/m", source', 'unit = "N/mm", source', "speed.ki_n_per_m: unit"),
    ('[launch]\n', '[launch]\nbogus = { value = 1 }\n', "launch.bogus: unknown key"),
    ('source = "chosen", how = "clutch safety', 'source = "guessed", how = "clutch safety', "strategy.T_safe_c"),
    ('how = "clutch safety temperature', 'how = " ", wrong = "clutch safety temperature', "strategy.T_safe_c.wrong"),
    ('[clutch.CH]', '[clutch.CX]', "clutch.CX"),
])
def test_bad_values_name_the_key(old, new, key):
    assert old in TEXT
    with pytest.raises(CalibrationError, match=key.replace(".", r"\.")):
        parse_calibration(TEXT.replace(old, new, 1))


def test_missing_key_and_bad_map_shape():
    lines = [line for line in TEXT.splitlines() if not line.startswith("standstill_mps")]
    with pytest.raises(CalibrationError, match=r"launch\.standstill_mps: missing"):
        parse_calibration("\n".join(lines))
    raw = raw_sections()
    raw["friction"]["mu"] = {**raw["friction"]["mu"], "value": [[[0.07, 0.07]]]}
    with pytest.raises(CalibrationError, match=r"friction\.mu: must be"):
        parse_calibration(dump_calibration(raw))


def test_cli_reports_a_bad_calibration_file(tmp_path, capsys):
    bad = tmp_path / "cal.toml"
    bad.write_text(TEXT.replace("[vehicle]", "[vehicle]\nm_kg = 1\n"), encoding="utf-8")
    assert main(["--calibration", str(bad), "--interface", "virtual", "--duration", "0.01"]) == 2
    assert "error:" in capsys.readouterr().err
