"""UDS (ISO 14229-1) services of ecu-stub: request bytes in, response bytes out (None: no response), never raising.

| SID | service | sub-functions / parameters | session |
|---|---|---|---|
| 0x10 | DiagnosticSessionControl | 0x01 default, 0x03 extended (P2 50 ms, P2* 5000 ms) | any |
| 0x3E | TesterPresent | 0x00 | any |
| 0x22 | ReadDataByIdentifier | one or more DIDs of the description | any |
| 0x19 | ReadDTCInformation | 0x01 / 0x02 number / list by status mask, 0x03 snapshot identification, | any |
| | | 0x04 snapshot record by DTC (record 1, or 0xFF all), 0x0A supported DTCs | |
| 0x14 | ClearDiagnosticInformation | group 0xFFFFFF (all) or one DTC | any |
| 0x85 | ControlDTCSetting | 0x01 on, 0x02 off (status bits frozen) | extended |

Bit 7 of a sub-function (suppressPosRspMsgIndicationBit) suppresses the positive response. Negative responses
(0x7F, SID, NRC): 0x11 service not supported, 0x12 sub-function not supported, 0x13 incorrect message length or
format, 0x22 conditions not correct (DIDs known, but no value yet: before the first control period), 0x31 request
out of range (no DID of the request known, an unknown DTC or record), 0x7F service not supported in the active
session. A non-default session falls back to default after S3 = 5 s without a request.
"""

from __future__ import annotations

from collections.abc import Callable

from dsg_hil.protocol.diag import DiagDescription

from .dtc import AVAILABILITY_MASK, DtcMemory

__all__ = ["DEFAULT", "EXTENDED", "NRC", "S3_S", "UdsServer"]

NRC = {"serviceNotSupported": 0x11, "subFunctionNotSupported": 0x12, "incorrectMessageLengthOrInvalidFormat": 0x13,
       "conditionsNotCorrect": 0x22, "requestOutOfRange": 0x31, "serviceNotSupportedInActiveSession": 0x7F}
S3_S = 5.0  # non-default session timeout
P2_MS, P2_STAR_10MS = 50, 500  # DiagnosticSessionControl's timing parameters (P2*: 10 ms units)
DEFAULT, EXTENDED = 0x01, 0x03
FORMAT_ISO14229 = 0x01  # DTCFormatIdentifier of reportNumberOfDTCByStatusMask
SNAPSHOT_RECORD = 0x01


def _negative(sid: int, code: str) -> bytes:
    return bytes((0x7F, sid, NRC[code]))


class UdsServer:
    """The services above over ``description`` (DIDs), ``memory`` (DTCs), ``read_did(did)`` (the DID's bytes now, or
    None if it cannot be read). Counts requests by SID and negative responses by NRC."""

    def __init__(self, description: DiagDescription, memory: DtcMemory,
                 read_did: Callable[[int], bytes | None]) -> None:
        self.description, self.memory, self.read_did = description, memory, read_did
        self.session = DEFAULT
        self.last_request = 0.0
        self.requests: dict[int, int] = {}
        self.negative: dict[int, int] = {}

    def handle(self, request: bytes, now: float) -> bytes | None:
        """One request -> its response (None: suppressed, or an empty request)."""
        if not request:
            return None
        self.expire(now)
        self.last_request = now
        sid = request[0]
        self.requests[sid] = self.requests.get(sid, 0) + 1
        try:
            response = self._dispatch(sid, request)
        except (IndexError, ValueError, KeyError):  # a request shaped in a way no branch foresaw: its length or form
            response = _negative(sid, "incorrectMessageLengthOrInvalidFormat")
        if response is not None and response[0] == 0x7F:
            self.negative[response[2]] = self.negative.get(response[2], 0) + 1
        return response

    def expire(self, now: float) -> None:
        """Back to the default session (and DTC recording on) once S3 has passed since the last request; the server
        calls it on every poll, so a tester that disappears cannot leave ControlDTCSetting off."""
        if self.session != DEFAULT and now - self.last_request > S3_S:
            self._leave_extended()

    def _leave_extended(self) -> None:
        self.session = DEFAULT
        self.memory.recording = True  # ControlDTCSetting is reset with the session (ISO 14229-1 9.9)

    def _dispatch(self, sid: int, request: bytes) -> bytes | None:
        service = {0x10: self._session, 0x3E: self._tester_present, 0x22: self._read_did, 0x19: self._read_dtc,
                   0x14: self._clear, 0x85: self._dtc_setting}.get(sid)
        if service is None:
            return _negative(sid, "serviceNotSupported")
        return service(request)

    @staticmethod
    def _sub(request: bytes, length: int | None) -> tuple[int, bool] | bytes:
        """The sub-function and whether the positive response is suppressed; or the NRC for a wrong length."""
        if len(request) < 2 or (length is not None and len(request) != length):
            return _negative(request[0], "incorrectMessageLengthOrInvalidFormat")
        return request[1] & 0x7F, bool(request[1] & 0x80)

    def _session(self, request: bytes) -> bytes | None:
        sub = self._sub(request, 2)
        if isinstance(sub, bytes):
            return sub
        session, suppress = sub
        if session not in (DEFAULT, EXTENDED):
            return _negative(0x10, "subFunctionNotSupported")
        if session == DEFAULT:
            self._leave_extended()
        self.session = session
        return None if suppress else bytes((0x50, session)) + P2_MS.to_bytes(2, "big") + \
            P2_STAR_10MS.to_bytes(2, "big")

    def _tester_present(self, request: bytes) -> bytes | None:
        sub = self._sub(request, 2)
        if isinstance(sub, bytes):
            return sub
        if sub[0] != 0:
            return _negative(0x3E, "subFunctionNotSupported")
        return None if sub[1] else b"\x7e\x00"

    def _read_did(self, request: bytes) -> bytes:
        if len(request) < 3 or len(request) % 2 != 1:
            return _negative(0x22, "incorrectMessageLengthOrInvalidFormat")
        out = bytearray(b"\x62")
        known = False
        for at in range(1, len(request), 2):
            did = int.from_bytes(request[at:at + 2], "big")
            if did in self.description.dids:
                known = True
                data = self.read_did(did)
                if data is not None:
                    out += did.to_bytes(2, "big") + data
        if len(out) > 1:
            return bytes(out)
        return _negative(0x22, "conditionsNotCorrect" if known else "requestOutOfRange")

    def _read_dtc(self, request: bytes) -> bytes | None:
        if len(request) < 2:
            return _negative(0x19, "incorrectMessageLengthOrInvalidFormat")
        sub, suppress = request[1] & 0x7F, bool(request[1] & 0x80)
        lengths = {0x01: 3, 0x02: 3, 0x03: 2, 0x04: 6, 0x0A: 2}
        if sub not in lengths:
            return _negative(0x19, "subFunctionNotSupported")
        if len(request) != lengths[sub]:
            return _negative(0x19, "incorrectMessageLengthOrInvalidFormat")
        head = bytes((0x59, sub))
        memory = self.memory
        if sub == 0x01:
            count = len(memory.matching(request[2]))
            response = head + bytes((AVAILABILITY_MASK, FORMAT_ISO14229)) + count.to_bytes(2, "big")
        elif sub in (0x02, 0x0A):
            records = memory.matching(request[2]) if sub == 0x02 else list(memory.records.values())
            response = head + bytes((AVAILABILITY_MASK,)) + b"".join(
                r.dtc.number.to_bytes(3, "big") + bytes((r.status,)) for r in records)
        elif sub == 0x03:
            response = head + b"".join(r.dtc.number.to_bytes(3, "big") + bytes((SNAPSHOT_RECORD,))
                                       for r in memory.records.values() if r.freeze_frame is not None)
        else:
            record = memory.by_number.get(int.from_bytes(request[2:5], "big"))
            if record is None or request[5] not in (SNAPSHOT_RECORD, 0xFF):
                return _negative(0x19, "requestOutOfRange")
            response = head + record.dtc.number.to_bytes(3, "big") + bytes((record.status,))
            if record.freeze_frame is not None:
                frame = record.freeze_frame
                response += bytes((SNAPSHOT_RECORD, len(frame))) + b"".join(
                    did.to_bytes(2, "big") + data for did, data in frame)
        return None if suppress else response

    def _clear(self, request: bytes) -> bytes:
        if len(request) != 4:
            return _negative(0x14, "incorrectMessageLengthOrInvalidFormat")
        group = int.from_bytes(request[1:4], "big")
        if group != 0xFFFFFF and group not in self.memory.by_number:
            return _negative(0x14, "requestOutOfRange")
        self.memory.clear(None if group == 0xFFFFFF else group)
        return b"\x54"

    def _dtc_setting(self, request: bytes) -> bytes | None:
        if self.session != EXTENDED:  # checked before the sub-function and length (ISO 14229-1 figure 5)
            return _negative(0x85, "serviceNotSupportedInActiveSession")
        sub = self._sub(request, None)
        if isinstance(sub, bytes):
            return sub
        if sub[0] not in (0x01, 0x02):
            return _negative(0x85, "subFunctionNotSupported")
        self.memory.recording = sub[0] == 0x01
        return None if sub[1] else bytes((0xC5, sub[0]))
