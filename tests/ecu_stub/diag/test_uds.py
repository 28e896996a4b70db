"""UDS services and DTC memory of ecu-stub on the shipped description: positive responses as ISO 14229-1 lays
them out, the standard negative responses, status bits through debounce, operation cycle and clear."""

from __future__ import annotations

import pytest

from dsg_hil.protocol.diag import dtc_code, dtc_number, load_description
from ecu_stub.diag.dtc import CONFIRMED, PENDING, TEST_FAILED, TEST_FAILED_THIS_CYCLE, DtcMemory
from ecu_stub.diag.uds import UdsServer

DESCRIPTION = load_description()


@pytest.fixture
def uds():
    memory = DtcMemory(DESCRIPTION.dtcs)
    return UdsServer(DESCRIPTION, memory, lambda did: DESCRIPTION.dids[did].encode({"T_CL_Pred": 187.4,
                                                                                    "T_CH_Pred": 101.2}))


def nrc(response):
    assert response is not None and response[0] == 0x7F
    return response[2]


def test_dtc_codes_round_trip():
    assert dtc_number("P1701") == 0x170100 and dtc_number("U1101") == 0xD10100
    assert dtc_code(0xD10100) == "U1101" and dtc_code(0x170105) == "P1701-05"


def test_session_and_tester_present(uds):
    assert uds.handle(b"\x10\x03", 0.0) == bytes((0x50, 0x03, 0x00, 50, 0x01, 0xF4))
    assert uds.handle(b"\x3e\x00", 1.0) == b"\x7e\x00"
    assert uds.handle(b"\x3e\x80", 2.0) is None  # suppressPosRspMsgIndicationBit
    assert uds.session == 0x03
    uds.handle(b"\x3e\x80", 8.0)  # 6 s later: S3 expired before this request
    assert uds.session == 0x01


def test_read_did(uds):
    response = uds.handle(b"\x22\x01\x01", 0.0)
    assert response[:3] == b"\x62\x01\x01"
    assert DESCRIPTION.dids[0x0101].decode(response[3:]) == pytest.approx({"T_CL_Pred": 187.4, "T_CH_Pred": 101.2})


@pytest.mark.parametrize(("request_", "code"), [
    (b"\x22\x01", 0x13), (b"\x22", 0x13), (b"\x22\xab\xcd", 0x31), (b"\x10\x02", 0x12), (b"\x10", 0x13),
    (b"\x10\x01\x00", 0x13), (b"\x3e\x01", 0x12), (b"\x19\x42", 0x12), (b"\x19\x02", 0x13), (b"\x19", 0x13),
    (b"\x19\x04\x12\x34\x56\x01", 0x31), (b"\x19\x04\x17\x01\x00\x02", 0x31), (b"\x14\xff\xff", 0x13),
    (b"\x14\x12\x34\x56", 0x31), (b"\x31\x01\x02\x03", 0x11), (b"\x85\x02", 0x7F), (b"\x27\x01", 0x11)])
def test_bad_requests_get_the_standard_negative_response(uds, request_, code):
    assert nrc(uds.handle(request_, 0.0)) == code


def test_a_known_did_without_a_value_yet_is_conditions_not_correct():
    """Before the TCU's first control period a known DID has no value: 0x22, not 0x31 (which says the DID does not
    exist, and made a tester give up on a TCU process still starting)."""
    server = UdsServer(DESCRIPTION, DtcMemory(DESCRIPTION.dtcs), lambda did: None)
    assert nrc(server.handle(b"\x22\x01\x01", 0.0)) == 0x22
    assert nrc(server.handle(b"\x22\xab\xcd", 0.0)) == 0x31


def test_empty_request_is_ignored(uds):
    assert uds.handle(b"", 0.0) is None


def test_debounce_confirms_with_freeze_frame_and_clear_clears(uds):
    memory = uds.memory
    name = "VehicleSpeed_implausible"  # debounce 3
    frame = ((0x0113, b"\x00\x00\x03\xe8"),)
    for n in range(2):
        assert not memory.report(name, True, n * 0.01, lambda: frame)
    assert memory.records[name].status & TEST_FAILED == 0
    assert memory.report(name, True, 0.02, lambda: frame)
    record = memory.records[name]
    assert record.status & (TEST_FAILED | CONFIRMED | PENDING | TEST_FAILED_THIS_CYCLE) == 0x0F
    assert record.freeze_frame == frame and record.failed_at == 0.02
    assert not memory.report(name, True, 0.03, lambda: ((0x0113, b"\xff" * 4),))  # still failed: no new count
    assert record.occurrences == 1
    memory.report(name, False, 0.04)
    assert record.status & TEST_FAILED == 0 and record.status & CONFIRMED

    number = uds.handle(b"\x19\x01\x08", 0.0)
    assert number == bytes((0x59, 0x01, 0x7F, 0x01, 0x00, 0x01))
    listed = uds.handle(b"\x19\x02\x08", 0.0)
    assert listed[3:6] == dtc_number("P1710").to_bytes(3, "big") and listed[6] & CONFIRMED
    snapshot = uds.handle(b"\x19\x04\x17\x10\x00\x01", 0.0)
    assert snapshot[2:5] == b"\x17\x10\x00" and snapshot[6:9] == b"\x01\x01\x01"  # record 1, one DID: 0x0113
    assert snapshot[9:] == b"\x13\x00\x00\x03\xe8"
    assert uds.handle(b"\x19\x03", 0.0) == b"\x59\x03\x17\x10\x00\x01"

    assert uds.handle(b"\x14\xff\xff\xff", 0.0) == b"\x54"
    assert record.status == 0x50 and record.freeze_frame is None
    assert uds.handle(b"\x19\x01\x08", 0.0)[-2:] == b"\x00\x00"


def test_operation_cycle_and_dtc_setting(uds):
    memory = uds.memory
    memory.report("overheat_stop", True, 0.0)
    memory.new_operation_cycle()
    record = memory.records["overheat_stop"]
    assert record.status & CONFIRMED and record.status & PENDING and not record.status & TEST_FAILED_THIS_CYCLE
    memory.report("overheat_stop", False, 0.0)
    memory.new_operation_cycle()  # a cycle that completed without failing: no longer pending, still confirmed
    assert record.status & CONFIRMED and not record.status & PENDING
    uds.handle(b"\x10\x03", 0.0)
    assert uds.handle(b"\x85\x02", 0.0) == b"\xc5\x02"
    memory.report("vehicle_hold", True, 0.0)
    assert memory.records["vehicle_hold"].status & TEST_FAILED == 0  # recording off
    uds.handle(b"\x10\x01", 0.0)  # back to default: recording on again
    memory.report("vehicle_hold", True, 0.0)
    assert memory.records["vehicle_hold"].status & CONFIRMED


def test_s3_expires_without_a_request():
    """A tester that turns DTC recording off and disappears: the server's poll (every control period, and the
    after-run server's loop) ends the extended session after S3, recording on again, with no further request."""
    from ecu_stub.diag.server import DiagServer
    from ecu_stub.diag.uds import S3_S

    now = [100.0]
    sent: list[tuple[int, bytes]] = []
    server = DiagServer(DESCRIPTION, 0x7E1, 0x7E9, lambda frame_id, data: sent.append((frame_id, data)), {}, {},
                        clock=lambda: now[0])
    server.take(bytes((0x02, 0x10, 0x03)) + bytes(5))  # single frames: extended session, then DTC setting off
    server.take(bytes((0x02, 0x85, 0x02)) + bytes(5))
    assert [data[1] for _, data in sent] == [0x50, 0xC5] and not server.memory.recording
    now[0] += S3_S / 2
    server.poll()
    assert server.uds.session == 0x03 and not server.memory.recording
    now[0] += S3_S
    server.poll()
    assert server.uds.session == 0x01 and server.memory.recording
