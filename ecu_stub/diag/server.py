"""ecu-stub's diagnostic server: ISO-TP (:mod:`.isotp`) carrying UDS (:mod:`.uds`) on the DBC's diagnostic IDs, and
the monitors that set the DTCs of the description (:mod:`.dtc`), judged once per control period.

Monitors (the ``monitor`` column of the description):

* ``state STOPPED_OVERHEAT``: the controller's state; ``hold``: the controller holds the vehicle by the brake because
  the clutches do not follow their commands (``held_untrusted``).
* ``implausible X``: a plausibility check replaced signal X this period (the runner's ``implausible`` counts:
  VehicleSpeed, speeds, P_CL, P_CH, ClutchInputSpeed, T_OilCL, T_OilCH); passed in a period the checks ran without it.
* ``timeout MSG``: MSG not fresh (3 cycle times, the receive check's), once it has been received; passed when fresh.
* ``e2e MSG``: a frame of MSG rejected this period (CRC, counter, range, DLC); passed when a new one was taken.

The transport and the session run on the wall clock (the tester's); the DTCs on the TCU's control periods, so a
lock-step run sets the same DTCs with the same freeze frames whatever the tester does.
"""

from __future__ import annotations

import hashlib
import threading
import time
from collections.abc import Callable, Mapping
from importlib import metadata

import can

from dsg_hil.protocol.diag import DiagDescription, DiagError
from dsg_hil.protocol.validity import RxMonitor, RxState, all_valid

from ..controller import TcuInputs, TcuOutputs
from .dtc import PASS_CLEARS, DtcMemory
from .isotp import IsoTpServer
from .uds import DEFAULT, UdsServer

__all__ = ["DiagServer", "response_frame", "software_version"]

KINDS = ("state", "hold", "implausible", "timeout", "e2e")


def response_frame(frame_id: int, data: bytes) -> can.Message:
    """A response frame: classic up to 8 bytes, else CAN FD (with bit rate switch)."""
    fd = len(data) > 8
    return can.Message(arbitration_id=frame_id, data=data, is_extended_id=False, is_fd=fd, bitrate_switch=fd)


def software_version() -> str:
    try:
        return f"dsg-hil {metadata.version('dsg-hil')}"
    except metadata.PackageNotFoundError:
        return "dsg-hil unknown"


class DiagServer:
    """Serves ``description`` on ``request_id``/``response_id``; ``send(frame_id, data)`` puts a frame on the bus
    (more than 8 bytes: CAN FD). ``states``/``clutches``: the DBC's value tables of TCU_STATUS; ``T_safe_c``: the
    calibration's safety temperature (the thermal margin's reference); ``calibration``: what identifies the
    calibration (hashed into DID calibration_id). ``messages``: the description's message names (the shipped
    DBC's) as the matrix names them, where it names them otherwise (a binding's, :meth:`ecu_stub.tcu_io.TcuIO.renames`).
    """

    def __init__(self, description: DiagDescription, request_id: int, response_id: int,
                 send: Callable[[int, bytes], None], states: Mapping[str, int], clutches: Mapping[str, int],
                 T_safe_c: float = float("nan"), calibration: str = "",
                 clock: Callable[[], float] = time.monotonic, messages: Mapping[str, str] | None = None) -> None:
        renamed = dict(messages or {})
        self.description, self.request_id, self.response_id = description, request_id, response_id
        self._send, self.clock = send, clock
        self.states, self.clutches, self.T_safe_c = states, clutches, T_safe_c
        self.memory = DtcMemory(description.dtcs)
        self.monitors: list[tuple[str, str, str]] = []  # (DTC name, kind, argument)
        for dtc in description.dtcs:
            kind, _, argument = dtc.monitor.partition(" ")
            if kind not in KINDS:
                raise DiagError(f"dtc {dtc.code}: monitor {dtc.monitor!r}: not one of ecu-stub's "
                                f"({', '.join(KINDS)})")
            if kind in ("timeout", "e2e"):
                argument = renamed.get(argument, argument)
            self.monitors.append((dtc.name, kind, argument))
        self.uds = UdsServer(description, self.memory, self.read_did)
        self.link = IsoTpServer(self._request)
        # the last control period's (values), the last valid inputs; by monitor the counts it saw last period
        self._now = 0.0
        self._inp: TcuInputs | None = None
        self._out: TcuOutputs | None = None
        self._cache: dict[str, float] | None = None
        self._judged: list[tuple[str, str, str, list[int]]] = [(*m, []) for m in self.monitors]
        # what lets a period skip the monitors (period): the DTC memory's changes when it was last seen settled, the
        # states that fail a monitor, the sums of the implausible and rejected counts, the timed messages' states
        self._settled_at = -1
        self._failing_states = {argument for _, kind, argument in self.monitors if kind == "state"}
        self._judges_hold = any(kind == "hold" for _, kind, _ in self.monitors)
        self._sums = (-1, -1)
        self._timeouts: tuple[RxMonitor, list[RxState]] | None = None
        self.texts = {"software_version": software_version(),
                      "calibration_id": hashlib.sha256(calibration.encode()).hexdigest()[:16].upper()}
        self.frames_sent = 0

    # -- the bus side
    def take(self, data: bytes) -> None:
        """A frame on the request ID."""
        self._transmit(self.link.feed(data, self.clock()))

    def _request(self, payload: bytes, now: float) -> None:
        response = self.uds.handle(payload, now)
        if response is not None:
            self._transmit(self.link.send(response, now))

    def _transmit(self, frames: list[bytes]) -> None:
        for data in frames:
            self._send(self.response_id, data)
            self.frames_sent += 1

    def poll(self) -> None:
        """Consecutive frames waiting for STmin; transport timeouts; the session's S3 timeout."""
        if self.uds.session == DEFAULT and not self.link.busy:
            return  # the usual period: nothing to send, no session to time out
        now = self.clock()
        self.uds.expire(now)
        if self.link.busy:
            self._transmit(self.link.poll(now))

    def serve(self, bus: can.BusABC, stop: threading.Event) -> None:
        """Answer requests on ``bus`` until ``stop`` is set: the TCU's diagnostics after its run (no control
        periods: the DTCs as the run left them), e.g. in a thread."""
        send, self._send = self._send, lambda frame_id, data: bus.send(response_frame(frame_id, data))
        try:
            while not stop.is_set():
                msg = bus.recv(timeout=0.01)
                if msg is not None and msg.arbitration_id == self.request_id and not msg.is_extended_id:
                    self.take(bytes(msg.data))
                self.poll()
        finally:
            self._send = send

    # -- the DIDs
    def read_did(self, did: int) -> bytes | None:
        entry = self.description.dids[did]
        if entry.ascii_length:
            return entry.encode(self.texts.get(entry.name, ""))
        values = self.values
        return entry.encode(values) if values else None

    # -- the monitors, once per control period
    def period(self, now: float, rx_now: float, rx: RxMonitor, implausible: Mapping[str, int], inp: TcuInputs,
               out: TcuOutputs, hold: bool) -> None:
        """Judge every monitor on this period's inputs ``inp`` and outputs ``out`` at TCU time ``now`` [s] (the
        freeze frames' time); ``rx_now``: the time the receive checks judge freshness at (the runner's). Runs in
        every ecu-stub period: a settled pass (nothing to change in the DTC) is skipped, the DIDs' values are made
        only when read (:attr:`values`)."""
        self._now, self._out, self._cache = now, out, None
        if inp.plant_valid or self._inp is None:  # while the plant's frames are missing: the last inputs it had
            self._inp = inp
        memory, records, state_name, plant_valid = self.memory, self.memory.records, out.state, inp.plant_valid
        states = rx.states
        # the usual period, every DTC settled and nothing that could fail them: no monitor can change a DTC
        implausible_n, rejected_n = sum(implausible.values()), sum(rx.rejected.values())
        if self._timeouts is None or self._timeouts[0] is not rx:
            self._timeouts = (rx, [states[argument] for _, kind, argument, _ in self._judged if kind == "timeout"])
        quiet = (self._settled_at == memory.changes and state_name not in self._failing_states
                 and not (hold and self._judges_hold) and implausible_n == self._sums[0]
                 and rejected_n == self._sums[1] and all_valid(self._timeouts[1], rx_now))
        self._sums = (implausible_n, rejected_n)
        if quiet:
            self.poll()
            return
        for name, kind, argument, last in self._judged:
            failed: bool | None
            if kind == "state":
                failed = state_name == argument
            elif kind == "hold":
                failed = hold
            elif kind == "implausible":
                n = implausible.get(argument, 0)
                failed = True if last and n > last[0] else (False if plant_valid else None)
                last[:] = (n,)
            else:
                state = states[argument]
                if kind == "timeout":
                    failed = None if state.last_time is None else not state.valid(rx_now)
                else:
                    received, rejected = state.received, sum(state.rejected.values())
                    failed = None if not last else (True if rejected > last[1] else
                                                    (False if received > last[0] else None))
                    last[:] = (received, rejected)
            if failed is None:
                continue
            if not failed:
                record = records[name]
                if not record.count and not record.status & PASS_CLEARS:
                    continue  # passed again: nothing to change
            memory.report(name, failed, now, self._freeze)
        if memory.settled():
            self._settled_at = memory.changes
        self.poll()

    def new_operation_cycle(self) -> None:
        """The TCU restarted (a lock-step run's presence probe)."""
        self.memory.new_operation_cycle()
        for *_, last in self._judged:
            last.clear()
        self._inp = self._out = self._cache = None

    def _freeze(self) -> tuple[tuple[int, bytes], ...]:
        dids, values = self.description.dids, self.values
        return tuple((did, dids[did].encode(values)) for did in self.description.snapshot)

    @property
    def values(self) -> dict[str, float]:
        """The DIDs' values of the last control period (empty before the first): the inputs the controller used
        (while the plant's frames are missing or untrusted, the last it had), its outputs, the thermal margin and
        the TCU's time."""
        inp, out = self._inp, self._out
        if inp is None or out is None:
            return {}
        if self._cache is None:
            T_safe = self.T_safe_c
            self._cache = {
                "EngineSpeed": inp.engine_speed_rpm, "ClutchInputSpeed": inp.clutch_in_rpm,
                "CLOutputSpeed": inp.cl_out_rpm, "CHOutputSpeed": inp.ch_out_rpm, "VehicleSpeed": inp.v_mps,
                "T_OilCL": inp.T_oil_CL_c, "T_OilCH": inp.T_oil_CH_c, "T_Sump": inp.T_sump_c,
                "P_CL": inp.P_CL_mpa, "P_CH": inp.P_CH_mpa,
                "t": self._now, "T_CL_Pred": out.T_CL_pred_c, "T_CH_Pred": out.T_CH_pred_c,
                "P_CL_Cmd": out.P_CL_cmd_mpa, "P_CH_Cmd": out.P_CH_cmd_mpa,
                "State": float(self.states.get(out.state, 0xFF)),
                "ActiveClutch": float(self.clutches.get(out.active_clutch, 0xFF)),
                "margin_CL": T_safe - out.T_CL_pred_c, "margin_CH": T_safe - out.T_CH_pred_c,
            }
        return self._cache
