"""python -m ecu_stub.identify on a recorded closed-loop run: fitted constants near the plant's, the TCU's plate
estimate replayed within a kelvin of the truth, a calibration written that loads."""

from __future__ import annotations

from dataclasses import replace

import can
import pytest

from dsg_hil.physics.friction import mean_friction_radius
from dsg_hil.physics.params import load_params
from ecu_stub.calibration import load_calibration
from ecu_stub.identify import main
from tests.sim.test_closed_loop import closed_loop, creep_scenario


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A short run with both clutches slipping, written as candump -L: a TCU with a low safety temperature hands
    over from CL to CH within seconds whatever the plant's thermal parameters."""
    path = tmp_path_factory.mktemp("identify") / "run.log"
    shipped = load_calibration()
    low = replace(shipped, strategy=replace(shipped.strategy, T_safe_c=shipped.strategy.T_safe_c - 110.0))
    _, _, frames = closed_loop(creep_scenario(12.0, T_oil=120.0, T_plates=(128.0, 100.0)), cal=low)
    with can.Logger(str(path)) as log:
        for t, frame_id, data in frames:
            log.on_message_received(can.Message(timestamp=t, arbitration_id=frame_id, data=data,
                                                is_extended_id=False, channel="vcan0"))
    return path


def test_identifies_the_clutch_constants_and_writes_a_calibration(recorded, tmp_path, capsys):
    out = tmp_path / "cal.toml"
    assert main([str(recorded), "--write", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "worst under-prediction" in printed
    cal = load_calibration(out)
    params = load_params()
    for name in ("CL", "CH"):
        g = getattr(params.clutch, name)
        assert cal.clutch(name).k_geom_m3 == pytest.approx(g.N * g.A_f * mean_friction_radius(g.R_i, g.R_o),
                                                           rel=0.01)
        assert cal.clutch(name).C_plate_j_k == pytest.approx(g.C_plate, rel=0.05)
    assert cal.CH.speed_ratio_m / cal.CL.speed_ratio_m == pytest.approx(params.powertrain.i_L / params.powertrain.i_H,
                                                                          rel=0.01)
    assert 0.0 < cal.strategy.prediction_error_k <= 1.0  # the TCU's estimate within a kelvin of the truth


def test_a_file_that_is_no_log_is_one_clear_error(tmp_path, capsys):
    bad = tmp_path / "x.log"
    bad.write_text("hello\n", encoding="utf-8")
    assert main([str(bad)]) == 2  # bad input (README, 'Exit codes')
    assert capsys.readouterr().err.startswith(f"error: {bad}: cannot read the log")
