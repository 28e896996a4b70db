"""The end-to-end protection as the contract states it: CRC parameters, coverage, positions read from the DBC,
and the receiver's counter rules."""

from __future__ import annotations

import can
import cantools
import pytest

from dsg_hil.protocol import MAX_DELTA, Codec, ProtocolError, RxMonitor, TxScheduler, crc8_j1850, load_dbc
from dsg_hil.protocol.e2e import Protection

from .dbcs import one_message_db


def test_crc_parameters_check_value_and_a_worked_frame():
    assert crc8_j1850(b"123456789") == 0x4B  # CRC-8 SAE J1850: poly 0x1D, init 0xFF, xorout 0xFF, not reflected
    assert crc8_j1850(b"") == 0x00  # init 0xFF, nothing shifted, final XOR 0xFF
    # TCU_CMD 0x200, P_CL_Cmd 0.5 MPa (raw 5000 = 0x1388), counter 3: CRC over 00 02 | 88 13 00 00 00 00 03
    codec = Codec(load_dbc(), {"TCU_CMD": ("P_CL_Cmd",)})
    data = codec.encode("TCU_CMD", {"P_CL_Cmd": 0.5, "P_CH_Cmd": 0.0, "SyncEcho": 0}, counter=3)
    assert data[:7] == bytes.fromhex("88130000000003")
    assert data[7] == crc8_j1850(bytes.fromhex("0002") + bytes.fromhex("88130000000003"))


def _db_with(crc_sig: str,
             counter_sig: str = " SG_ Counter : 48|4@1+ (1,0) [0|15] \"-\" B") -> cantools.database.Database:
    return one_message_db(8, f' SG_ Value : 8|16@1+ (1,0) [0|1000] "-" B\n{counter_sig}\n{crc_sig}')


def test_positions_come_from_the_dbc():
    db = _db_with(' SG_ CRC : 0|8@1+ (1,0) [0|255] "-" B', ' SG_ Counter : 56|8@1+ (1,0) [0|255] "-" B')
    codec = Codec(db, {"MSG": ("Value",)})
    p = codec.protection("MSG")
    assert p == Protection(0x100, 8, 0, 256)
    data = codec.encode("MSG", {"Value": 300}, counter=200)
    assert data[7] == 200 and data[0] == crc8_j1850(bytes((0x00, 0x01)) + data[1:])
    assert codec.decode(0x100, data).counter == 200


@pytest.mark.parametrize("crc_sig, words", [
    (' SG_ CRC : 60|4@1+ (1,0) [0|15] "-" B', "8 unsigned bits"),
    (' SG_ CRC : 52|8@1+ (1,0) [0|255] "-" B', "byte boundary"),
])
def test_a_crc_that_cannot_carry_the_scheme_fails_at_start_up(crc_sig, words):
    with pytest.raises(ProtocolError, match=words):
        Codec(_db_with(crc_sig), {"MSG": ("Value",)})


def _frames(codec, counters, t0=0.0, period=0.01):
    msgs = []
    for k, c in enumerate(counters):
        data = codec.encode("TCU_CMD", {"P_CL_Cmd": 0.1 + 0.01 * k}, counter=c)  # values move: no duplicates
        msgs.append(can.Message(arbitration_id=0x200, data=data, is_extended_id=False, timestamp=t0 + k * period))
    return msgs


def test_counter_rules():
    codec = Codec(load_dbc(), {"TCU_CMD": ("P_CL_Cmd",)})
    rx = RxMonitor(codec, ["TCU_CMD"])
    counters = [9, 10, 10, 12, 12 + MAX_DELTA, 3]  # first any; repeat; gap of 1; largest gap; step 8: out of order
    accepted = [rx.receive(m, m.timestamp) is not None for m in _frames(codec, [c % 16 for c in counters])]
    assert accepted == [True, True, False, True, True, False]
    state = rx.states["TCU_CMD"]
    assert rx.rejected["counter"] == 2 and state.counter_jumps == 2 and state.lost == 1 + (MAX_DELTA - 1)
    assert state.duplicates == 0


def test_a_byte_identical_repeat_is_a_duplicate_not_an_error():
    codec = Codec(load_dbc(), {"TCU_CMD": ("P_CL_Cmd",)})
    rx = RxMonitor(codec, ["TCU_CMD"])
    first = _frames(codec, [4])[0]
    assert rx.take(first, 0.0)[0] == "new" and rx.take(first, 0.001)[0] == "duplicate"
    assert rx.rejected_total == 0 and rx.states["TCU_CMD"].duplicates == 1


def test_resynchronised_after_a_timeout():
    codec = Codec(load_dbc(), {"TCU_CMD": ("P_CL_Cmd",)})
    rx = RxMonitor(codec, ["TCU_CMD"])
    first = _frames(codec, [5])[0]
    later = _frames(codec, [13], t0=1.0)[0]  # step 8 would be out of order, but the message timed out meanwhile
    assert rx.receive(first, 0.0) is not None and rx.receive(later, 1.0) is not None


def test_sender_counter_wraps_at_the_dbc_width():
    codec = Codec(load_dbc(), {"TCU_CMD": ("P_CL_Cmd",)})
    tx = TxScheduler(codec, ["TCU_CMD"])
    counters = [codec.decode(0x200, bytes(tx.frame("TCU_CMD", {}).data)).counter for _ in range(18)]
    assert counters == list(range(16)) + [0, 1]


def test_a_repeated_counter_is_refused_even_after_a_timeout():
    codec = Codec(load_dbc(), {"TCU_CMD": ("P_CL_Cmd",)})
    rx = RxMonitor(codec, ["TCU_CMD"])
    first, frozen = _frames(codec, [5, 5], period=1.0)  # same counter, other values, after the 30-ms deadline
    assert rx.receive(first, first.timestamp) is not None
    assert rx.receive(frozen, frozen.timestamp) is None and rx.rejected["counter"] == 1


def test_the_contract_page_shows_the_codecs_worked_examples():
    """The contract's worked example frames on the CAN contract page are what the codec encodes (skipped without a
    checkout: an installed package has no docs/)."""
    from pathlib import Path

    from dsg_hil.protocol.examples import example_frames

    readme = Path(__file__).resolve().parents[2] / "docs" / "reference" / "can.md"
    if not readme.exists():
        pytest.skip("no docs/ beside the tests (installed package)")
    text = readme.read_text(encoding="utf-8")
    db = load_dbc()
    frames = example_frames(db)
    assert {name for name, *_ in frames} == {m.name for m in db.messages}  # every message has its example
    for name, frame_id, _, data in frames:
        assert f"| 0x{frame_id:03X} | {name} |" in text and f"`{data.hex(' ').upper()}`" in text, name


def test_frames_seen_again_are_not_decoded_again_and_bad_ones_never_pass():
    """RxMonitor keeps frames decoded by their bytes (a steady plant repeats them): the same frame again, without
    decoding; a corrupted frame rejected every time; a bytearray taken as its bytes."""
    codec = Codec(load_dbc(), {"TCU_CMD": ("P_CL_Cmd",)})
    rx = RxMonitor(codec, ["TCU_CMD"])
    frame_id = codec.frame_id("TCU_CMD")
    calls = []
    state, decode, memo = rx._by_id[frame_id]
    rx._by_id[frame_id] = (state, lambda data: calls.append(data) or decode(data), memo)
    data = [codec.encode("TCU_CMD", {"P_CL_Cmd": 0.5, "SyncEcho": 0}, counter=c % 16) for c in range(40)]
    taken = [rx.take_data(frame_id, d, 0.01 * i) for i, d in enumerate(data)]
    assert [status for status, _ in taken] == ["new"] * 40 and len(calls) == 16  # 16 counter values
    assert [f.counter for _, f in taken] == [c % 16 for c in range(40)]
    assert taken[17][1] == taken[1][1] == codec.decode(frame_id, data[1])
    bad = data[3][:7] + bytes([data[3][7] ^ 1])
    assert [rx.take_data(frame_id, bad, 0.5)[0] for _ in range(3)] == ["rejected"] * 3 and rx.rejected["crc"] == 3
    assert rx.take_data(frame_id, bytearray(data[0]), 0.6)[0] == "new"
