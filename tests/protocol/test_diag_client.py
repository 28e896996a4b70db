"""The tester's UDS client on a caller's bus: it filters the bus to its response ID while open and gives the caller's
filters back when it closes, also when the body raises (the fixture's and ``dsg-hil diag``'s bus goes on receiving)."""

from __future__ import annotations

from contextlib import nullcontext

import can
import pytest

pytest.importorskip("udsoncan", reason="extra diag")

from dsg_hil.protocol.diag import load_description  # noqa: E402
from dsg_hil.protocol.diag_client import uds_client  # noqa: E402

CALLERS = [{"can_id": 0x101, "can_mask": 0x7FF, "extended": False}]


@pytest.mark.parametrize("raises", [False, True], ids=["closes", "raises"])
def test_the_callers_filters_come_back(raises):
    with can.Bus(interface="virtual", channel="diag-client-filters", receive_own_messages=False) as bus:
        bus.set_filters(CALLERS)
        with pytest.raises(RuntimeError) if raises else nullcontext():
            with uds_client(bus, load_description(), 0x7E1, 0x7E9, timeout=0.1):
                assert bus.filters == [{"can_id": 0x7E9, "can_mask": 0x7FF, "extended": False}]
                if raises:
                    raise RuntimeError("the test's body failed")
        assert bus.filters == CALLERS

