"""The direct in-process bus: what python-can's ``virtual`` interface does for two nodes (own copy, stamped,
``is_rx``, the channel), a receive with a timeout that waits and is woken by a sender in another thread, and
closed ends; and the closed loop on it gives the frames of python-can's ``virtual`` with the cantools codec, bit
for bit."""

from __future__ import annotations

import threading
import time

import can
import pytest

from dsg_hil.sim.loop import run_closed_loop
from dsg_hil.protocol.frame import data_frame
from dsg_hil.protocol.local import local_pair
from dsg_hil.sim.scenario import load_scenario


def fields(msg: can.Message) -> dict:
    return {name: getattr(msg, name) for name in can.Message.__slots__ if name not in ("__weakref__", "timestamp")}


@pytest.fixture
def pair():
    a, b = local_pair("test")
    yield a, b
    a.shutdown()
    b.shutdown()


def test_the_receiver_gets_what_python_can_virtual_gives(pair):
    a, b = pair
    va, vb = can.Bus(interface="virtual", channel="test"), can.Bus(interface="virtual", channel="test")
    try:
        for msg in (data_frame(0x123, b"\x01\x02\x03", timestamp=5.0),
                    can.Message(arbitration_id=0x1ABCDE, data=bytes(8), is_extended_id=True),
                    can.Message(arbitration_id=0x7FF, is_remote_frame=True, dlc=4, is_extended_id=False)):
            before = time.time()
            a.send(msg)
            va.send(msg)
            got, want = b.recv(0.0), vb.recv(1.0)
            assert fields(got) == fields(want) and got.is_rx and got.channel == "test"
            assert before <= got.timestamp <= time.time()
            assert got is not msg and got.data is not msg.data and a.recv(0.0) is None  # a copy; not to oneself
    finally:
        va.shutdown()
        vb.shutdown()


def test_order_is_kept_and_an_empty_bus_answers_none_at_once(pair):
    a, b = pair
    for i in range(5):
        b.send(data_frame(i, bytes([i])))
    assert [a.recv(0.0).arbitration_id for _ in range(5)] == list(range(5))
    t0 = time.monotonic()
    assert a.recv(0.0) is None and a.recv(0.05) is None
    assert time.monotonic() - t0 >= 0.05


def test_a_waiting_receiver_is_woken_by_a_sender_in_another_thread(pair):
    a, b = pair
    sender = threading.Timer(0.05, lambda: a.send(data_frame(0x42, b"\x00")))
    sender.start()
    msg = b.recv(timeout=10.0)
    sender.join()
    assert msg is not None and msg.arbitration_id == 0x42


def test_closed_ends(pair):
    a, b = pair
    b.shutdown()
    a.send(data_frame(1, b""))  # nobody listening: gone, as on a bus
    a.shutdown()
    with pytest.raises(can.CanOperationError):
        a.send(data_frame(1, b""))
    with pytest.raises(can.CanOperationError):
        a.recv(0.0)


def test_closed_loop_frames_are_those_of_python_can_virtual_and_cantools_bit_for_bit():
    scenario = load_scenario().with_duration(3.0)
    runs = {(transport, reference): run_closed_loop(scenario, capture=True, transport=transport,
                                                    reference_codec=reference)
            for transport, reference in (("local", False), ("virtual", True))}
    frames = {key: [(m.timestamp, m.arbitration_id, bytes(m.data), m.is_rx) for m in run.frames]
              for key, run in runs.items()}
    assert len(frames["local", False]) > 1000 and frames["local", False] == frames["virtual", True]
    summaries = [{k: v for k, v in run.summary.items() if k not in ("wall_time_s", "interface")}
                 for run in runs.values()]
    assert summaries[0] == summaries[1]
    with pytest.raises(ValueError, match="transport 'vcan'"):
        run_closed_loop(scenario, transport="vcan")
