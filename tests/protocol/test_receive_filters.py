"""A node's bus passes only the DBC messages it reads (python-can filters; kernel filters on SocketCAN)."""

from __future__ import annotations

import can

from dsg_hil.sim.plant_io import PLANT_RX
from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.bus import open_bus, receive_filters


def test_filters_pass_exactly_the_messages_read():
    db = load_dbc()
    wanted = [db.get_message_by_name(name) for name in PLANT_RX]
    filters = receive_filters(wanted)
    assert {f["can_id"] for f in filters} == {m.frame_id for m in wanted}
    assert all(f["can_mask"] == 0x7FF and f["extended"] is False for f in filters)


def test_a_filtered_bus_never_returns_other_frames():
    db = load_dbc()
    cmd = db.get_message_by_name("TCU_CMD")
    config = {"interface": "virtual", "channel": "test_receive_filters"}
    with open_bus(config, receive=[cmd]) as node, can.Bus(**config) as other:
        for ident in (0x5A5, cmd.frame_id | 0x400, cmd.frame_id):
            other.send(can.Message(arbitration_id=ident, data=bytes(8), is_extended_id=False))
        other.send(can.Message(arbitration_id=cmd.frame_id, data=bytes(8), is_extended_id=True))
        got = [node.recv(timeout=0.5) for _ in range(2)]
    assert got[0] is not None and got[0].arbitration_id == cmd.frame_id and not got[0].is_extended_id
    assert got[1] is None
