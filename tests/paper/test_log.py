"""The log reader (dsg_hil.paper.report.log) and the plant's encoder agree through one table
(dsg_hil.sim.plant_io.SIGNALS): a plant's frames written to a log read back as its outputs in SI."""

from __future__ import annotations

import can
import pytest

from dsg_hil.paper.report.log import SIGNALS, LogSample, read_log
from dsg_hil.physics.plant import PlantOutputs
from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.sim.plant_io import PLANT_TX, SIGNALS as PLANT_SIGNALS, plant_signals
from dsg_hil.sim.scenario import DriverInput


def test_the_reader_takes_the_plants_table_for_its_fields():
    assert SIGNALS == {key: (LogSample._fields.index(name), factor) for key, (name, factor) in PLANT_SIGNALS.items()
                       if name in LogSample._fields}
    assert {LogSample._fields[i] for i, _ in SIGNALS.values()} == set(LogSample._fields) - {"t"}  # each one filled


def test_frames_encoded_by_the_plant_read_back_as_its_outputs(tmp_path):
    db = load_dbc()
    codec = Codec(db, {**PLANT_TX, "TCU_CMD": ("P_CL_Cmd", "P_CH_Cmd", "SyncEcho")})
    out = PlantOutputs(*([0.0] * len(PlantOutputs._fields)))._replace(
        omega_in=84.3, omega_CL=41.2, omega_CH=-12.5, v=0.206, P_CL=0.5e6, P_CH=0.7345e6, T_CL=180.25, T_CH=99.5,
        mu_CL=0.0625, mu_CH=0.071, M_CL=310.0, M_CH=-25.0, Q_CL=12840.0, Q_CH=300.0, Q_diss_CL=2140.0,
        Q_diss_CH=160.0)
    driver = DriverInput(0.0, True, 0.0, 0.206)
    values = plant_signals(out, driver)
    values["TCU_CMD"] = {"P_CL_Cmd": 0.55, "P_CH_Cmd": 1.2, "SyncEcho": 0.0}
    path = tmp_path / "one_period.log"
    with can.Logger(str(path)) as log:
        for name, signals in values.items():
            data = codec.encode(name, signals, 0)
            log(can.Message(timestamp=100.0, arbitration_id=codec.frame_id(name), data=data, is_extended_id=False))
    record = read_log(path, db)
    assert record.frames["decoded"] == len(values) and record.frames["rejected"] == 0
    last = {name: float(column[-1]) for name, column in record.columns.items()}
    checked = set()
    for (message, signal), (name, factor) in PLANT_SIGNALS.items():
        if message in PLANT_TX and name in last and message != "DRIVER":
            half_step = db.get_message_by_name(message).get_signal_by_name(signal).scale * factor / 2  # SI
            assert abs(last[name] - getattr(out, name)) <= half_step * (1 + 1e-9), name
            checked.add(name)
    assert len(checked) == 16
    assert last["P_CL_cmd"] == pytest.approx(0.55e6) and last["P_CH_cmd"] == pytest.approx(1.2e6)
    assert last["creep_request"] == 1.0 and last["desired_speed_mps"] == pytest.approx(0.206)
