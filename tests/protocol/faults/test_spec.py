"""Fault specifications: the --fault syntax, TOML tables, and clear errors naming what is wrong."""

from __future__ import annotations

import math

import pytest

from dsg_hil.protocol.faults import FaultError, FaultSpec, check_against_dbc, fault_from_mapping, parse_fault
from dsg_hil.protocol import load_dbc


def test_cli_syntax_round_trip():
    spec = parse_fault("drop:TCU_CMD@10-12,probability=0.5")
    assert spec == FaultSpec(kind="drop", target="TCU_CMD", start_s=10.0, end_s=12.0, probability=0.5)
    assert parse_fault("stuck:PLANT_VEHICLE.VehicleSpeed@40-,value=0").end_s == math.inf
    assert parse_fault("stuck:PLANT_VEHICLE.VehicleSpeed@40-,value=0").signal == "VehicleSpeed"
    flood = parse_fault("flood@5-15,rate=20,id=0x5A6")
    assert flood.frame_id == 0x5A6 and flood.rate == 20 and flood.message is None
    assert parse_fault("delay:TCU_CMD,delay=0.03").delay_s == 0.03


def test_toml_table_same_as_cli():
    table = {"kind": "offset", "target": "PLANT_OIL_TEMP.T_OilCL", "start_s": 1, "end_s": 2, "value": 20}
    assert fault_from_mapping(table) == parse_fault("offset:PLANT_OIL_TEMP.T_OilCL@1-2,value=20")
    gain = {"kind": "gain", "target": "PLANT_SPEEDS.ClutchInputSpeed", "start_s": 0, "value": 0.95}
    assert fault_from_mapping(gain) == parse_fault("gain:PLANT_SPEEDS.ClutchInputSpeed@0-,value=0.95")
    assert parse_fault(parse_fault("gain:PLANT_SPEEDS.ClutchInputSpeed@0-,value=0.95").as_option()).value == 0.95


@pytest.mark.parametrize("text, words", [
    ("explode:TCU_CMD", "kind must be one of"),
    ("drop", "needs a target"),
    ("stuck:TCU_CMD", "MESSAGE.Signal"),
    ("drop:TCU_CMD.P_CL_Cmd", "takes a MESSAGE target"),
    ("drop:TCU_CMD@5", "START-END"),
    ("drop:TCU_CMD@5-2", "start_s < end_s"),
    ("drop:TCU_CMD,probability=2", "probability"),
    ("drop:TCU_CMD,probability=often", "must be a number"),
    ("drop:TCU_CMD,colour=red", "unknown key 'colour'"),
    ("drop:TCU_CMD,fast", "key=value"),
    ("wrong_dlc:TCU_CMD,dlc=9", "dlc must be a frame length: 0-8, or on a CAN FD message 12, 16"),
    ("wrong_dlc:TCU_CMD,dlc=65", "dlc must be a frame length"),
    ("flood:TCU_CMD", "flood takes no target"),
    ("flood,rate=1.5", "whole number"),
    ("gain:PLANT_OIL_TEMP.T_OilCL", "gain needs a non-zero value"),  # the default value 0 would zero it
    ("gain:PLANT_OIL_TEMP", "MESSAGE.Signal"),
])
def test_bad_specs_say_what_is_wrong(text, words):
    with pytest.raises(FaultError, match=words):
        parse_fault(text)


def test_targets_are_checked_against_the_dbc():
    db = load_dbc()
    check_against_dbc(parse_fault("stuck:PLANT_VEHICLE.VehicleSpeed,value=0"), db)
    with pytest.raises(FaultError, match="message 'NOPE'"):
        check_against_dbc(parse_fault("drop:NOPE"), db)
    with pytest.raises(FaultError, match="signal 'TCU_CMD.Nope'"):
        check_against_dbc(parse_fault("stuck:TCU_CMD.Nope,value=1"), db)
    with pytest.raises(FaultError, match="is a DBC message"):
        check_against_dbc(parse_fault("flood,frame_id=0x200"), db)
