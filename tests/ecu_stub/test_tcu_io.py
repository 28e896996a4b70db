"""ecu-stub's side of a binding (ecu_stub/tcu_io.py): the shipped pair gives the tables ecu-stub was written with,
the unit conversion is the identity where the units agree, and an unmapped input is refused naming the file."""

from __future__ import annotations

import pytest

from dsg_hil.common.units import CV
from dsg_hil.protocol.binding import DEFAULT_BINDING, BindingError, load_binding
from ecu_stub.runner import REQUIRED, TCU_RX, TCU_TX, TX_VALUES
from ecu_stub.tcu_io import INPUTS, TcuIO, edge

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
