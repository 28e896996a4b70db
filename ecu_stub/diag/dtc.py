"""Trouble codes with the status bits of ISO 14229-1 (annex D.2), debounced per control period, each with one
freeze frame.

Each control period every monitor reports failed (True), passed (False) or no result (None: e.g. a 100-ms message
not due). Counter debounce (as AUTOSAR Dem's): +1 per failed period, a passed period resets the count (a jump down);
``debounce`` failed periods in a row make the test failed: testFailed, testFailedThisOperationCycle, pending and
confirmed (confirmation threshold: one failed test), testFailedSinceLastClear set, the not-completed bits cleared,
and, the first time since a clear, the freeze frame taken (snapshot record 1: the period's values). A passed test
clears testFailed and, once the counter is back at 0, the test counts as completed. The count is per control
period, so frames a lock-step plant re-sends, or a message's several frames in one period, count once.

A new operation cycle (the TCU's restart: a lock-step run's presence probe) clears testFailedThisOperationCycle and
sets testNotCompletedThisOperationCycle; a pending DTC whose test completed without a failure in the cycle before
is no longer pending. ClearDiagnosticInformation resets status (to 0x50), counters and freeze frames.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

from dsg_hil.protocol.diag import Dtc

__all__ = ["AVAILABILITY_MASK", "CONFIRMED", "PASS_CLEARS", "PENDING", "TEST_FAILED", "TEST_FAILED_SINCE_CLEAR",
           "TEST_FAILED_THIS_CYCLE", "TEST_NOT_COMPLETED_SINCE_CLEAR", "TEST_NOT_COMPLETED_THIS_CYCLE",
           "DtcMemory", "DtcRecord"]

TEST_FAILED = 0x01
TEST_FAILED_THIS_CYCLE = 0x02
PENDING = 0x04
CONFIRMED = 0x08
TEST_NOT_COMPLETED_SINCE_CLEAR = 0x10
TEST_FAILED_SINCE_CLEAR = 0x20
TEST_NOT_COMPLETED_THIS_CYCLE = 0x40
WARNING_INDICATOR = 0x80  # not supported: no lamp
AVAILABILITY_MASK = 0x7F
CLEARED = TEST_NOT_COMPLETED_SINCE_CLEAR | TEST_NOT_COMPLETED_THIS_CYCLE
PASS_CLEARS = TEST_FAILED | TEST_NOT_COMPLETED_SINCE_CLEAR | TEST_NOT_COMPLETED_THIS_CYCLE  # the bits a pass clears


class DtcRecord:
    """One DTC's state: status byte, debounce count, occurrences (passes to failed since the clear), freeze frame
    (``(DID, data)`` pairs; None until the first confirmation)."""

    def __init__(self, dtc: Dtc) -> None:
        self.dtc = dtc
        self.status = CLEARED
        self.count = 0
        self.occurrences = 0
        self.freeze_frame: tuple[tuple[int, bytes], ...] | None = None
        self.failed_at: float | None = None  # the TCU time of the first confirmation since the clear [s]

    def clear(self) -> None:
        self.status, self.count, self.occurrences, self.freeze_frame, self.failed_at = CLEARED, 0, 0, None, None


class DtcMemory:
    """The DTCs of ``dtcs``, by name (monitor results by DTC name)."""

    def __init__(self, dtcs: Sequence[Dtc]) -> None:
        self.records = {d.name: DtcRecord(d) for d in dtcs}
        self.by_number = {r.dtc.number: r for r in self.records.values()}
        self.recording = True  # ControlDTCSetting off: the status bits are frozen
        self.changes = 0  # +1 whenever a status or count may have changed (a monitor's cache key)

    def report(self, name: str, failed: bool | None, now: float,
               freeze: Callable[[], Iterable[tuple[int, bytes]]] | None = None) -> bool:
        """One control period's result of the monitor of DTC ``name``; True when it became testFailed. ``freeze``:
        gives the period's freeze frame (called only if the DTC is confirmed now for the first time since the clear)."""
        record = self.records[name]
        if failed is None or not self.recording:
            return False
        self.changes += 1
        if not failed:
            record.count = 0
            record.status &= ~PASS_CLEARS
            return False
        record.count += 1
        if record.count < record.dtc.debounce or record.status & TEST_FAILED:
            return False
        record.status |= TEST_FAILED | TEST_FAILED_THIS_CYCLE | PENDING | CONFIRMED | TEST_FAILED_SINCE_CLEAR
        record.status &= ~(TEST_NOT_COMPLETED_SINCE_CLEAR | TEST_NOT_COMPLETED_THIS_CYCLE)
        record.occurrences += 1
        if record.freeze_frame is None:
            record.freeze_frame = tuple(freeze()) if freeze is not None else ()
            record.failed_at = now
        return True

    def new_operation_cycle(self) -> None:
        self.changes += 1
        for record in self.records.values():
            status = record.status
            if status & PENDING and not status & TEST_FAILED_THIS_CYCLE and not status & TEST_NOT_COMPLETED_THIS_CYCLE:
                status &= ~PENDING
            record.status = (status & ~(TEST_FAILED_THIS_CYCLE | TEST_FAILED)) | TEST_NOT_COMPLETED_THIS_CYCLE
            record.count = 0

    def clear(self, number: int | None = None) -> None:
        """Clear one DTC (by its number) or all (None)."""
        self.changes += 1
        for record in self.records.values() if number is None else (self.by_number[number],):
            record.clear()

    def settled(self) -> bool:
        """Whether a passed result would change no DTC (every count 0, no bit a pass clears set)."""
        return not any(r.count or r.status & PASS_CLEARS for r in self.records.values())

    def matching(self, mask: int) -> list[DtcRecord]:
        """The DTCs whose status has a bit of ``mask`` (ISO 14229-1: status & mask != 0), in table order."""
        return [r for r in self.records.values() if r.status & mask & AVAILABILITY_MASK]
