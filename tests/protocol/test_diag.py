"""The diagnostic contract: the DBC's IDs, the shipped description (every DTC's monitor, snapshot DIDs described),
DIDs packed as described, and a bad description named by file and key."""

from __future__ import annotations

import pytest

from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.diag import DiagError, diag_ids, load_description

REQUIRED = ("PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER")


def test_ids_in_the_dbc_do_not_collide():
    db = load_dbc()
    request, response = diag_ids(db)
    assert (request, response) == (0x7E1, 0x7E9)
    assert not {request, response} & {m.frame_id for m in db.messages}


def test_shipped_description_covers_every_fault_the_tcu_detects():
    description = load_description()
    monitors = {d.monitor for d in description.dtcs}
    for name in REQUIRED:
        assert f"timeout {name}" in monitors and f"e2e {name}" in monitors
    for signal in ("VehicleSpeed", "speeds", "P_CL", "P_CH", "ClutchInputSpeed", "T_OilCL", "T_OilCH"):
        assert f"implausible {signal}" in monitors
    assert {"state STOPPED_OVERHEAT", "hold"} <= monitors
    assert all(did in description.dids for did in description.snapshot)


def test_did_round_trip_and_clamp():
    did = load_description().dids[0x0110]
    values = {"EngineSpeed": 800.0, "ClutchInputSpeed": -149.3, "CLOutputSpeed": 60.6, "CHOutputSpeed": 35.1,
              "VehicleSpeed": 0.22}
    assert did.decode(did.encode(values)) == pytest.approx(values)
    assert did.decode(did.encode({**values, "VehicleSpeed": 99.0}))["VehicleSpeed"] == pytest.approx(32.767)
    with pytest.raises(DiagError, match="0x0110"):
        did.decode(b"\x00")


@pytest.mark.parametrize(("text", "match"), [
    ("[[did]]\nid = 70000\n", r"did\[0\]: id"),
    ("[[did]]\nid = 1\nfields = [{name = 'x', type = 'f64'}]\n", r"did\[0\]\.fields\[0\]: type"),
    ("[[did]]\nid = 1\n", r"did\[0\]: give kind"),
    ("[[dtc]]\ncode = 'X1234'\n", r"dtc\[0\]: DTC code"),
    ("snapshot = [5]\n", "snapshot: DID 5"),
    ("request_id = 4096\n", "request_id"),
    ("[[dtc\n", "diag.toml"),
])
def test_bad_description_names_file_and_key(tmp_path, text, match):
    path = tmp_path / "diag.toml"
    path.write_text(text)
    with pytest.raises(DiagError, match=match) as info:
        load_description(path)
    assert str(path) in str(info.value)


def test_missing_description_file(tmp_path):
    with pytest.raises(DiagError, match="nope.toml"):
        load_description(tmp_path / "nope.toml")
