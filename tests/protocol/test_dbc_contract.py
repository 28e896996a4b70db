"""The DBC is the contract: complete, consistent, loadable without warnings, and light on the bus."""

from __future__ import annotations

import warnings

import cantools
import pytest

from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.busload import bus_load, frame_bits
from dsg_hil.protocol.codec import DEFAULT_DBC


@pytest.fixture(scope="module")
def db():
    return load_dbc()


def test_loads_strictly_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cantools.database.load_string(DEFAULT_DBC.read_text(encoding="utf-8"), "dbc", strict=True)


def test_nodes_ids_and_frames(db):
    assert {n.name for n in db.nodes} == {"PLANT", "TCU"}
    ids = [m.frame_id for m in db.messages]
    assert len(ids) == len(set(ids))
    for m in db.messages:
        assert not m.is_extended_frame and m.frame_id < 0x800 and m.length == 8, m.name
        assert m.senders and m.senders[0] in ("PLANT", "TCU"), m.name
        assert m.cycle_time and m.cycle_time > 0, f"{m.name} has no GenMsgCycleTime"
        assert m.comment, m.name


def test_every_signal_has_unit_range_comment(db):
    for m in db.messages:
        for s in m.signals:
            assert s.unit, f"{m.name}.{s.name} has no unit"
            assert s.minimum is not None and s.maximum is not None and s.minimum < s.maximum, f"{m.name}.{s.name}"
            assert s.comment, f"{m.name}.{s.name} has no comment"
        assert {"Counter", "CRC"} <= {s.name for s in m.signals}, m.name


def test_what_each_side_sends(db):
    plant = {m.name for m in db.messages if m.senders == ["PLANT"]}
    tcu = {m.name for m in db.messages if m.senders == ["TCU"]}
    assert {"PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER"} <= plant
    assert tcu == {"TCU_CMD", "TCU_STATUS"}
    state = db.get_message_by_name("TCU_STATUS").get_signal_by_name("State")
    assert "STOPPED_OVERHEAT" in {str(v) for v in state.choices.values()}


def test_simulation_only_frames_are_marked(db):
    for m in db.messages:
        if m.name.startswith("SIM_"):
            assert m.frame_id >= 0x700 and "Simulation only" in m.comment
        else:
            assert m.frame_id < 0x700


def test_receivers_get_initial_values(db):
    cmd = db.get_message_by_name("TCU_CMD")
    assert cmd.get_signal_by_name("P_CL_Cmd").initial == 0.0 and cmd.get_signal_by_name("P_CH_Cmd").initial == 0.0
    assert db.get_message_by_name("PLANT_OIL_TEMP").get_signal_by_name("T_Sump").initial == pytest.approx(25.0)


def test_bus_load_under_30_percent(db):
    assert frame_bits(8) == 135 and frame_bits(0) == 55  # worst-case stuffing, classic standard frames
    total, rows = bus_load(db, 500_000)
    assert len(rows) == len(db.messages)
    assert 0.10 < total < 0.30
