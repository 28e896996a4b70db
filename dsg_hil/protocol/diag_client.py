"""The tester side of the diagnostic contract: a UDS client (``udsoncan``) over ISO-TP (``can-isotp``) on a
python-can bus, for ecu-stub or any ECU given its IDs and a description (:mod:`.diag`); extra ``diag``.

``with uds_client(bus) as client:`` gives an ``udsoncan.client.Client`` whose DIDs decode by the description;
:func:`read_dtcs`, :func:`read_dids` and :func:`clear_dtcs` are what ``dsg-hil diag`` prints and a test asserts.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import can

from ..common.errors import InputError
from .diag import DiagDescription, Did, dtc_code

__all__ = ["STATUS_BITS", "DtcReport", "clear_dtcs", "read_dids", "read_dtcs", "uds_client"]

STATUS_BITS = ("testFailed", "testFailedThisOperationCycle", "pending", "confirmed",
               "testNotCompletedSinceLastClear", "testFailedSinceLastClear", "testNotCompletedThisOperationCycle",
               "warningIndicatorRequested")  # ISO 14229-1 D.2, bit 0 first


@dataclass(frozen=True)
class DtcReport:
    """A DTC as read: its number and code, its name in the description (the code if not described), the status
    byte and its set bits' names, and its freeze frame (snapshot record 1: ``{field: value}``; None: none)."""

    number: int
    code: str
    name: str
    status: int
    bits: tuple[str, ...]
    freeze_frame: dict[str, Any] | None

    def as_json(self) -> dict[str, Any]:
        return {"code": self.code, "name": self.name, "status": f"0x{self.status:02X}", "bits": list(self.bits),
                "freeze_frame": self.freeze_frame}


def _codec(did: Did) -> Any:
    from udsoncan import DidCodec  # noqa: PLC0415 - extra diag

    class Codec(DidCodec):
        def encode(self, *args: Any, **kwargs: Any) -> bytes:
            return did.encode(args[0] if args else kwargs)

        def decode(self, payload: bytes) -> Any:
            return did.decode(bytes(payload))

        def __len__(self) -> int:
            return did.size

    return Codec()


@contextmanager
def uds_client(bus: can.BusABC, description: DiagDescription, request_id: int, response_id: int, *,
               fd: bool = False, timeout: float = 2.0) -> Iterator[Any]:
    """An open ``udsoncan.client.Client`` on ``bus`` (normal 11-bit addressing: requests on ``request_id``,
    responses on ``response_id``; ``fd``: CAN FD frames of 64 bytes). ``timeout`` [s]: per request. While the client is
    open the bus's receive filters are set to ``response_id`` (on a busy bus the ISO-TP stack would read every frame);
    the caller's filters are set back when it closes, however it closes."""
    try:
        import isotp  # noqa: PLC0415 - extra diag
        from udsoncan.client import Client  # noqa: PLC0415
        from udsoncan.connections import PythonIsoTpConnection  # noqa: PLC0415
    except ImportError as exc:
        raise InputError(f"diag: needs the extra 'diag' (pip install 'dsg-hil[diag]'): {exc}") from exc
    callers_filters = bus.filters
    address = isotp.Address(isotp.AddressingMode.Normal_11bits, txid=request_id, rxid=response_id)
    params = {"tx_data_length": 64 if fd else 8, "can_fd": fd, "tx_padding": 0xCC, "blocking_send": False}
    stack = isotp.CanStack(bus, address=address, params=params)
    config: Any = {"data_identifiers": {did: _codec(entry) for did, entry in description.dids.items()},
              "request_timeout": timeout, "p2_timeout": timeout, "p2_star_timeout": timeout,
              "use_server_timing": False, "exception_on_negative_response": True}
    bus.set_filters([{"can_id": response_id, "can_mask": 0x7FF, "extended": False}])  # a busy bus: ISO-TP sees its own
    try:
        with Client(PythonIsoTpConnection(stack), config=config) as client:
            yield client
    finally:
        bus.set_filters(callers_filters)


def read_dtcs(client: Any, description: DiagDescription, mask: int = 0xFF,
              snapshots: bool = True) -> list[DtcReport]:
    """The DTCs whose status matches ``mask`` (ReadDTCInformation 0x02), each with its freeze frame (0x04)."""
    response = client.get_dtc_by_status_mask(mask)
    reports = []
    for dtc in response.service_data.dtcs:
        status = dtc.status.get_byte_as_int()
        described = description.dtc(dtc.id)
        frame: dict[str, Any] | None = None
        if snapshots:
            snap = client.get_dtc_snapshot_by_dtc_number(dtc.id, record_number=1).service_data.dtcs
            if snap and snap[0].snapshots:
                frame = {}
                for record in snap[0].snapshots:
                    value = record.data
                    frame.update(value if isinstance(value, dict) else {description.dids[record.did].name: value})
        reports.append(DtcReport(dtc.id, dtc_code(dtc.id), described.name if described else dtc_code(dtc.id),
                                 status, tuple(b for n, b in enumerate(STATUS_BITS) if status >> n & 1), frame))
    return reports


def read_dids(client: Any, description: DiagDescription, dids: Iterable[int]) -> dict[str, Any]:
    """ReadDataByIdentifier of ``dids``, one request each: ``{DID name: value}`` (fields, or the text)."""
    values = {}
    for did in dids:
        response = client.read_data_by_identifier([did])
        values[description.dids[did].name] = response.service_data.values[did]
    return values


def clear_dtcs(client: Any, group: int = 0xFFFFFF) -> None:
    """ClearDiagnosticInformation (all by default)."""
    client.clear_dtc(group)
