"""The ISO-TP server end, fed frames and time: single and multi-frame both ways, flow control, STmin, block size,
timeouts, CAN FD, and malformed frames dropped (counted), never raised."""

from __future__ import annotations

import pytest

from ecu_stub.diag.isotp import IsoTpServer, st_min_s


@pytest.fixture
def link():
    got: list[bytes] = []
    server = IsoTpServer(lambda payload, now: got.append(payload))
    server.got = got
    return server


def test_single_frame_request_and_response(link):
    assert link.feed(bytes((0x02, 0x3E, 0x00)), 0.0) == []
    assert link.got == [b"\x3e\x00"]
    assert link.send(b"\x7e\x00", 0.0) == [bytes((0x02, 0x7E, 0x00)) + b"\xcc" * 5]


def test_multi_frame_request_gets_flow_control_and_is_delivered(link):
    payload = bytes(range(20))
    fc = link.feed(bytes((0x10, 20)) + payload[:6], 0.0)
    assert fc == [bytes((0x30, 0, 0)) + b"\xcc" * 5]
    link.feed(bytes((0x21,)) + payload[6:13], 0.01)
    assert link.got == []
    link.feed(bytes((0x22,)) + payload[13:20] + b"\x00", 0.02)
    assert link.got == [payload]


def test_wrong_sequence_number_ends_reception(link):
    link.feed(bytes((0x10, 20)) + bytes(6), 0.0)
    link.feed(bytes((0x22,)) + bytes(7), 0.01)
    assert link.got == [] and link.dropped["sequence"] == 1


def test_consecutive_frame_after_n_cr_is_dropped(link):
    link.feed(bytes((0x10, 20)) + bytes(6), 0.0)
    link.feed(bytes((0x21,)) + bytes(7), 1.5)
    assert link.dropped["timeout"] == 1 and link.got == []


def test_multi_frame_response_waits_for_flow_control_block_size_and_st_min(link):
    payload = bytes(range(40))  # FF 6 bytes, then 34 in 5 CFs
    first = link.send(payload, 0.0)
    assert first == [bytes((0x10, 40)) + payload[:6]]
    assert link.poll(0.5) == []  # no CF before the flow control
    frames = link.feed(bytes((0x30, 2, 10)), 0.5)  # block size 2, STmin 10 ms
    assert [f[0] for f in frames] == [0x21]
    assert link.poll(0.505) == []
    assert [f[0] for f in link.poll(0.51)] == [0x22]
    assert link.poll(0.6) == []  # block done: waits for the next flow control
    rest = link.feed(bytes((0x30, 0, 0)), 0.6)
    assert [f[0] for f in rest] == [0x23, 0x24, 0x25]


def test_response_reassembles(link):
    payload = bytes(range(100))
    frames = link.send(payload, 0.0) + link.feed(bytes((0x30, 0, 0)), 0.0)
    length = ((frames[0][0] & 0x0F) << 8) | frames[0][1]
    data = frames[0][2:] + b"".join(f[1:] for f in frames[1:])
    assert length == 100 and data[:100] == payload
    assert [f[0] & 0x0F for f in frames[1:]] == [(n + 1) & 0x0F for n in range(len(frames) - 1)]


def test_flow_control_never_comes(link):
    link.send(bytes(30), 0.0)
    assert link.poll(1.5) == [] and not link.busy and link.dropped["timeout"] == 1


def test_overflow_and_wait(link):
    link.send(bytes(30), 0.0)
    assert link.feed(bytes((0x31, 0, 0)), 0.1) == [] and link.busy  # wait: still sending
    assert link.feed(bytes((0x32, 0, 0)), 0.2) == [] and not link.busy


def test_request_longer_than_the_buffer_gets_overflow():
    server = IsoTpServer(lambda p, t: None, max_length=100)
    assert server.feed(bytes((0x11, 0x00)) + bytes(6), 0.0)[0][0] == 0x32


@pytest.mark.parametrize("frame", [b"", b"\x00", b"\x05\x01", b"\x40\x01", b"\x10\x05" + bytes(6), b"\x21\x00",
                                   b"\x30\x00\x00", b"\x10"])
def test_malformed_or_unexpected_frames_are_dropped(link, frame):
    assert link.feed(frame, 0.0) == []
    assert link.got == [] and sum(link.dropped.values()) == 1


def test_can_fd_single_frame_and_answer_in_fd():
    got: list[bytes] = []
    server = IsoTpServer(lambda payload, now: got.append(payload))
    request = bytes((0x00, 20)) + bytes(range(20)) + b"\xcc" * 2  # 24-byte FD frame, escape length
    server.feed(request, 0.0)
    assert got == [bytes(range(20))] and server.frame_length == 24
    reply = server.send(bytes(range(22)), 0.0)
    assert reply == [bytes((0x00, 22)) + bytes(range(22))]
    long = server.send(bytes(100), 0.0)
    assert len(long[0]) == 24 and long[0][:2] == bytes((0x10, 100))


def test_st_min_encoding():
    assert st_min_s(0) == 0.0 and st_min_s(0x7F) == 0.127 and st_min_s(0xF1) == pytest.approx(1e-4)
    assert st_min_s(0x80) == 0.127
