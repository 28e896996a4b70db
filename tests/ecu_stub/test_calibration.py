"""The TCU calibration file: the shipped one loads and says how each value was obtained; bad files fail naming
the key."""

from __future__ import annotations

import tomllib

import pytest

from ecu_stub.calibration import DEFAULT_CALIBRATION, CalibrationError, FrictionMap, dump_calibration, \
    load_calibration, parse_calibration, raw_sections, torque_falls
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


def test_torque_falls_by_hand():
    """M = mu P on one node, pressures 1 and 2 MPa: mu 0.2 -> 0.15 gives M 0.2 -> 0.3, rising (dM/dP = a + 2 b P,
    a = 0.25, b = -0.05: 0.15 and 0.05); mu 0.2 -> 0.05 gives 0.2 -> 0.1 (dM/dP 0.05 at 1 MPa, -0.25 at 2 MPa);
    mu 0.2 -> 0.1 gives 0.2 -> 0.2, flat at 2 MPa (dM/dP 0.1 and -0.1: falling inside the span, M 0.225 at
    1.5 MPa)."""
    def node(mu_hi: float) -> FrictionMap:
        return FrictionMap((20.0, 300.0), (0.0, 100.0), (1.0, 2.0), (((0.2, mu_hi),) * 2,) * 2)

    assert torque_falls(node(0.15)) is None
    assert torque_falls(node(0.05)) == (20.0, 0.0, 1.0, 2.0)
    assert torque_falls(node(0.1)) == (20.0, 0.0, 1.0, 2.0)
    assert torque_falls(load_calibration().friction) is None  # the shipped map: one pressure for each torque


def test_a_map_whose_torque_falls_with_pressure_is_refused():
    raw = raw_sections()
    mu = [[list(cell) for cell in row] for row in raw["friction"]["mu"]["value"]]
    T, slip, P = raw["friction"]["T_grid_c"]["value"], raw["friction"]["slip_grid_rpm"]["value"], \
        raw["friction"]["P_grid_mpa"]["value"]
    k = P.index(1.0)
    mu[3][5][k + 1] = 0.5 * mu[3][5][k] * P[k] / P[k + 1]  # M at the next node half of M at 1 MPa
    raw["friction"]["mu"] = {**raw["friction"]["mu"], "value": mu}
    with pytest.raises(CalibrationError) as exc:
        parse_calibration(dump_calibration(raw))
    assert str(exc.value) == (f"friction.mu: the torque mu P falls as the pressure rises at {T[3]:g} degC, "
                              f"{slip[5]:g} r/min, 1-{P[k + 1]:g} MPa (the pressure for a torque needs it rising)")


def test_cli_reports_a_bad_calibration_file(tmp_path, capsys):
    bad = tmp_path / "cal.toml"
    bad.write_text(TEXT.replace("[vehicle]", "[vehicle]\nm_kg = 1\n"), encoding="utf-8")
    assert main(["--calibration", str(bad), "--interface", "virtual", "--duration", "0.01"]) == 2
    assert "error:" in capsys.readouterr().err
