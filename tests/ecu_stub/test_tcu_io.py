"""ecu-stub's side of a binding (ecu_stub/tcu_io.py): the shipped pair gives the tables ecu-stub was written with,
the unit conversion is the identity where the units agree, and an unmapped input is refused naming the file; the
plausibility checks' steps and times are the shipped constants on the shipped pair, another matrix's on it."""

from __future__ import annotations

from pathlib import Path

import can
import pytest

from dsg_hil.common.units import CV
from dsg_hil.protocol.binding import DEFAULT_BINDING, BindingError, load_binding
from dsg_hil.protocol.binding import Binding, shipped_binding
from dsg_hil.protocol.codec import Codec
from ecu_stub.controller import SHAFT_Q_RPM, SPEED_Q_MPS, V_STEP_MPS, CreepController
from ecu_stub.plausibility import MAX_DT_S
from ecu_stub.runner import REQUIRED, TCU_RX, TCU_TX, TX_VALUES, TcuRunner
from ecu_stub.sensor_checks import OIL_FRAME_S, MatrixSteps
from ecu_stub.tcu_io import INPUTS, SHIPPED, TcuIO, edge

DCT_FD = Path(__file__).parents[2] / "dbc" / "examples" / "dct_fd"

# the tables ecu_stub/runner.py wrote out by hand before they were derived from the binding
WRITTEN_RX = {
    "PLANT_ENGINE": ("EngineSpeed",), "PLANT_SPEEDS": ("ClutchInputSpeed", "CLOutputSpeed", "CHOutputSpeed"),
    "PLANT_VEHICLE": ("VehicleSpeed", "LongAccel"), "PLANT_PRESSURE": ("P_CL", "P_CH"),
    "PLANT_OIL_TEMP": ("T_OilCL", "T_OilCH", "T_Sump"), "DRIVER": ("CreepRequest", "BrakePedal", "DesiredCreepSpeed"),
    "SIM_SYNC": ("Tick",),
}
WRITTEN_TX_VALUES = {
    "TCU_STATUS": {"State": "states[out.state]", "ActiveClutch": "clutches[out.active_clutch]",
                   "BrakeRequest": "float(out.brake_request)", "T_CL_Pred": "out.T_CL_pred_c",
                   "T_CH_Pred": "out.T_CH_pred_c", "FaultBits": "out.fault_bits"},
    "TCU_CMD": {"P_CL_Cmd": "out.P_CL_cmd_mpa", "P_CH_Cmd": "out.P_CH_cmd_mpa", "SyncEcho": "echo",
                "DecelRequest": "out.decel_request_mps2"},
}


def test_the_shipped_pair_gives_the_tables_ecu_stub_was_written_with():
    assert TCU_RX == WRITTEN_RX and list(TX_VALUES) == list(WRITTEN_TX_VALUES) == list(TCU_TX)
    assert TX_VALUES == WRITTEN_TX_VALUES
    assert REQUIRED == ("PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER")


def test_the_edge_is_the_identity_where_the_units_agree_and_converts_where_not():
    for unit in ("rpm", "r/min", "MPa", "%", "degC", "m/s", "1"):
        assert edge(unit, unit) == (1.0, 0.0)
    assert edge("r/min", "rpm") == (1.0, 0.0)  # two spellings, one factor
    assert edge("km/h", "m/s") == (CV.KMH_TO_MPS, 0.0)
    assert edge("kPa", "MPa") == (CV.KPA_TO_PA / CV.MPA_TO_PA, 0.0)
    k, c = edge("K", "degC")
    assert (k, c) == (1.0, -CV.ZERO_C_IN_K) and edge("degC", "K") == (1.0, CV.ZERO_C_IN_K)
    assert edge("rad/s", "rpm")[0] == pytest.approx(CV.RAD_S_TO_RPM, rel=1e-15)


@pytest.mark.parametrize("quantity", list(INPUTS))
def test_an_input_left_unmapped_is_refused_naming_the_file_and_the_quantity(tmp_path, quantity):
    text = DEFAULT_BINDING.read_text(encoding="utf-8")
    lines = [line for line in text.splitlines() if not line.startswith(f"{quantity} = ")]
    assert len(lines) == len(text.splitlines()) - 1
    path = tmp_path / "partial.binding.toml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    binding = load_binding(path)  # the plant does not need it
    with pytest.raises(BindingError, match=rf"^{path}: quantities\.{quantity}: not mapped, and ecu-stub reads it"):
        TcuIO(binding)


def test_an_output_left_unmapped_is_not_sent(tmp_path):
    path = tmp_path / "nodecel.binding.toml"
    path.write_text(DEFAULT_BINDING.read_text(encoding="utf-8").replace('decel_request = "TCU_CMD.DecelRequest"\n',
                                                                        ""), encoding="utf-8")
    io = TcuIO(load_binding(path))
    assert io.tx["TCU_CMD"] == ("P_CL_Cmd", "P_CH_Cmd", "SyncEcho") and "DecelRequest" not in io.tx_values["TCU_CMD"]
    assert io.step("decel_request") == 0.0


def checks_of(binding: Binding, controller: CreepController | None = None) -> tuple[float, ...]:
    """What the TCU built on ``binding`` takes of the matrix: its controller's half step of VehicleSpeed, its steady
    band, its half steps of the shaft speeds, its oil frame; the speed vote's and the sensor checks' longest cycle,
    the sensor checks' oil frame."""
    io = TcuIO(binding)
    bus = can.Bus(interface="virtual", channel=f"matrix-steps-{id(io)}")
    try:
        codec = Codec(binding.db, io.uses, protection=io.protection, timeouts=io.timeouts)
        tcu = TcuRunner(codec, bus, controller, io=io)
    finally:
        bus.shutdown()
    c, vote, checks = tcu.controller, tcu.speed_vote, tcu.sensor_checks
    assert isinstance(c, CreepController) and vote is not None and checks is not None
    return (c.speed_q_mps, c.v_steady_step_mps, c.shaft_q_rpm, c.oil_frame_s, vote.max_dt_s, checks.max_dt_s,
            checks.oil_frame_s)


def test_on_the_shipped_pair_the_checks_take_exactly_the_constants_they_were_written_with():
    """Bit for bit: the shipped DBC's 30-ms receive timeout of the speed frames, its 100-ms oil frame, the half
    steps of VehicleSpeed (0.5 mm/s) and of the shaft speeds (0.05 + 0.05 r/min), a step and 10 % of VehicleSpeed."""
    assert SHIPPED.matrix_steps == MatrixSteps() == MatrixSteps(0.03, 0.1, 0.001, 0.1, 0.1)
    shipped = (SPEED_Q_MPS, V_STEP_MPS, SHAFT_Q_RPM, OIL_FRAME_S, MAX_DT_S, MAX_DT_S, OIL_FRAME_S)
    assert shipped == (0.0005, 0.0011, 0.1, 0.1, 0.03, 0.03, 0.1)
    assert checks_of(shipped_binding()) == shipped  # the runner's own controller
    assert checks_of(shipped_binding(), CreepController()) == shipped  # one given, built as the FMI TCU builds it


def test_on_the_example_matrix_the_checks_take_its_steps_and_times(tmp_path):
    """dct_fd: VehSpd in steps of 0.01 km/h, the shaft speeds of 0.05 rad/s, the oil temperatures in a message of
    50 ms multiplexed in two pages (each value every 100 ms), the speed frames at 10 ms (30-ms timeout); and with
    its binding's cycle time of the oil message and timeout of the vehicle speed's message overridden."""
    binding = load_binding(DCT_FD / "dct_fd.binding.toml", dbc=DCT_FD / "dct_fd.dbc")
    io = TcuIO(binding)
    v_step, shaft_step = 0.01 * CV.KMH_TO_MPS, 0.05 * CV.RAD_S_TO_RPM
    steps = io.matrix_steps
    assert (steps.max_dt_s, steps.oil_frame_s) == (0.03, 0.1)
    assert steps.v_step_mps == pytest.approx(v_step, rel=1e-15) and steps.v_step_mps != 0.001
    assert steps.shaft_step_rpm == steps.input_step_rpm == pytest.approx(shaft_step, rel=1e-15)
    expected = (0.5 * v_step, 1.1 * v_step, shaft_step, 0.1, 0.03, 0.03, 0.1)
    assert checks_of(binding) == pytest.approx(expected, rel=1e-15)
    text = (DCT_FD / "dct_fd.binding.toml").read_text(encoding="utf-8")
    text = text.replace('[messages.TCM_OilTemps]\n', '[messages.TCM_OilTemps]\ncycle_time_ms = 40\n')
    text = text.replace('[messages.ESP_WheelAccel]\n', '[messages.ESP_WheelAccel]\ntimeout_ms = 45\n')
    path = tmp_path / "slower.binding.toml"
    path.write_text(text, encoding="utf-8")
    slower = load_binding(path, dbc=DCT_FD / "dct_fd.dbc")
    other = TcuIO(slower).matrix_steps
    assert (other.max_dt_s, other.oil_frame_s) == (0.045, 0.08)
    assert checks_of(slower, CreepController(None, other))[3:] == (0.08, 0.045, 0.045, 0.08)
