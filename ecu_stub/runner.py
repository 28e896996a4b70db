"""The TCU process: owns its bus, decodes the plant's frames, runs the controller each command cycle.

Lock-step or real time is decided by the plant: once a SIM_SYNC tick has been seen, the TCU answers each tick
(controller time = tick x cycle time) and sends nothing on its own. It transmits nothing before it has heard the
plant, and free-runs on its monotonic clock at the TCU_CMD cycle time only when no tick has come within
``SYNC_WAIT_S`` of the plant's first frame (a real-time plant sends no ticks). A lock-step plant first probes for
the TCU (SIM_SYNC with Tick 0xFFFFFFFF): the TCU resets itself and answers, and the run starts from there.

Lost frames cost a retry, not the run: a plant that hears no answer re-sends the period's frames and its tick;
the TCU answers a repeated tick (or probe) with the very frames it already sent for it, byte for byte (same
counters), without stepping again. Repeats of frames it already has are duplicates: counted and ignored, not
errors. A tick whose plant frames are incomplete (the lock-step plant sends every message due at the tick's time,
each on its DBC cycle from t = 0) waits for them: it is answered when the last one comes (delivered after the tick,
as several CPUs may deliver, or re-sent with the period); only the third sight of the same tick is answered with
what the TCU has (counted as ``incomplete_answers``).

Listeners (``--log``) get every frame the TCU took (new, valid) and every frame it sent, first transmissions
only (neither the presence handshake nor re-sent answers), as the plant logs its side: in lock-step stamped with
the tick's time, so the same run gives the same record; else with the wall clock.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import can

from dsg_hil.protocol import Codec, ProtocolError, RxMonitor, TxScheduler
from dsg_hil.protocol.frame import data_frame
from dsg_hil.protocol.validity import DUPLICATE, IGNORED, NEW

from .controller import CreepController, TcuInputs, TcuOutputs

log = logging.getLogger(__name__)

TCU_RX = {
    "PLANT_ENGINE": ("EngineSpeed",),
    "PLANT_SPEEDS": ("ClutchInputSpeed", "CLOutputSpeed", "CHOutputSpeed"),
    "PLANT_VEHICLE": ("VehicleSpeed",),
    "PLANT_PRESSURE": ("P_CL", "P_CH"),
    "PLANT_OIL_TEMP": ("T_OilCL", "T_OilCH", "T_Sump"),
    "DRIVER": ("CreepRequest", "BrakePedal", "DesiredCreepSpeed"),
    "SIM_SYNC": ("Tick",),
}
TCU_TX = {
    "TCU_CMD": ("P_CL_Cmd", "P_CH_Cmd", "SyncEcho"),
    "TCU_STATUS": ("State", "ActiveClutch", "BrakeRequest", "T_CL_Pred", "T_CH_Pred", "FaultBits"),
}
TCU_USES = {**TCU_RX, **TCU_TX}
REQUIRED = ("PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER")
FAULT_BITS = {"crc": 0x02, "counter": 0x04, "range": 0x08, "dlc": 0x08, "malformed": 0x08}
SYNC_WAIT_S = 1.0  # plant heard this long without a SIM_SYNC: it runs in real time
SYNC_PROBE = 0xFFFFFFFF  # SIM_SYNC Tick of the lockstep presence probe (see the DBC comment)
SIGHTS_BEFORE_INCOMPLETE = 3  # lock-step: a tick seen this often is answered even with plant frames missing
DRAIN_MAX = 256  # real time: frames already waiting taken before a control cycle, at most (a busy bus: go on)


def _choices(codec: Codec, message: str, signal: str) -> dict[str, int]:
    choices = codec.message(message).get_signal_by_name(signal).choices
    return {str(name): int(value) for value, name in (choices or {}).items()}


class TcuRunner:
    def __init__(self, codec: Codec, bus: can.BusABC, controller: CreepController | None = None,
                 listeners: tuple[Callable[[can.Message], None], ...] = ()) -> None:
        for name in TCU_USES:
            codec.message(name)
        self.codec, self.bus = codec, bus
        self.listeners = listeners
        self._channel = getattr(bus, "channel", None)  # of the frames recorded for the listeners
        # the direct in-process bus (dsg_hil.protocol.local, unwrapped): frames as (ID, data), no can.Message
        self._send_data: Callable[[int, bytes], None] | None = getattr(bus, "send_data", None)
        self._recv_data: Callable[[float], tuple[int, bytes] | can.Message | None] | None = \
            getattr(bus, "recv_data", None)
        self.controller = controller or CreepController()
        self.rx = RxMonitor(codec, list(TCU_RX))
        self.tx = TxScheduler(codec, list(TCU_TX))
        self.cycle = codec.cycle_time("TCU_CMD")
        self.states = _choices(codec, "TCU_STATUS", "State")
        self.clutches = _choices(codec, "TCU_STATUS", "ActiveClutch")
        missing = {"IDLE", "ENGAGE", "CREEP", "HANDOVER", "STOPPED_OVERHEAT", "FAULT"} - set(self.states)
        if missing or {"NONE", "CL", "CH"} - set(self.clutches):
            raise ProtocolError(f"DBC TCU_STATUS lacks VAL_ entries the TCU needs: {sorted(missing)}")
        self.lockstep = False
        self._sim_now = 0.0  # lock-step: the time of the last tick answered [s]
        self.now = -1.0  # the TCU's time of the frames it sends (fault windows): tick time, or run time; < 0 before
        self.heard_plant_at: float | None = None
        self.last: TcuOutputs | None = None
        self._answered: int | None = None  # lock-step: the tick last answered (SYNC_PROBE: the probe) ...
        self._answer: list[tuple[int, bytes]] = []  # ... the frames (ID, data) sent for it, re-sent if repeated ...
        self._answer_sends = 0  # ... and how often they were sent
        self._pending: int | None = None  # lock-step: a tick not answered for want of plant frames ...
        self._pending_sights = 0  # ... and how often it was seen
        self._answered_early = False  # the tick answered came before its last plant frame (see handle_data)
        self._due_every = {name: round(codec.cycle_time(name) / self.cycle) for name in REQUIRED
                           if abs(codec.cycle_time(name) / self.cycle - round(codec.cycle_time(name) / self.cycle))
                           < 1e-9}  # lock-step: message due at every n-th tick
        self.sent = 0
        self.answers_resent = 0
        self.incomplete_answers = 0

    def inputs(self, now: float) -> TcuInputs:
        states = self.rx.states
        faults = 0
        if self.rx.rejected:
            for reason, n in self.rx.rejected.items():
                if n:
                    faults |= FAULT_BITS.get(reason, 0)
        engine, speeds, vehicle, pressure, oil, driver = required = [states[name] for name in REQUIRED]
        if not all(state.valid(now) for state in required):
            return TcuInputs(plant_valid=False, fault_bits=faults)
        e, s, v, p, o, d = engine.values, speeds.values, vehicle.values, pressure.values, oil.values, driver.values
        return TcuInputs(True, e["EngineSpeed"], s["ClutchInputSpeed"], s["CLOutputSpeed"], s["CHOutputSpeed"],
                         v["VehicleSpeed"], p["P_CL"], p["P_CH"], o["T_OilCL"], o["T_OilCH"], o["T_Sump"],
                         d["CreepRequest"] >= 0.5, d["BrakePedal"], d["DesiredCreepSpeed"], faults)

    def control(self, now: float, echo: int = 0) -> list[tuple[int, bytes]]:
        """One controller cycle at ``now``: compute, then send TCU_STATUS when due and TCU_CMD, last (in lock-step
        it completes the answer to the tick); returns the frames sent, as (ID, data)."""
        self.now = now
        out = self.controller.update(self.inputs(now), now)
        self.last = out
        tx, frames = self.tx, []
        due = tx.due(now)
        if "TCU_STATUS" in due:
            frames.append((tx.ids["TCU_STATUS"], tx.data("TCU_STATUS", {
                "State": self.states[out.state], "ActiveClutch": self.clutches[out.active_clutch],
                "BrakeRequest": float(out.brake_request), "T_CL_Pred": out.T_CL_pred_c,
                "T_CH_Pred": out.T_CH_pred_c, "FaultBits": out.fault_bits})))
        if "TCU_CMD" in due:
            frames.append((tx.ids["TCU_CMD"], tx.data("TCU_CMD", {
                "P_CL_Cmd": out.P_CL_cmd_mpa, "P_CH_Cmd": out.P_CH_cmd_mpa, "SyncEcho": echo})))
        self._send(frames)
        if self.listeners:
            for frame_id, data in frames:
                self._record(frame_id, data, now, is_rx=False)
        return frames

    def _record(self, frame_id: int, data: bytes, stamp: float, is_rx: bool) -> None:
        """Hand a frame taken or sent to the listeners, stamped ``stamp`` (lock-step), else with the wall clock."""
        msg = data_frame(frame_id, data, stamp if self.lockstep else time.time(), self._channel, is_rx)
        for listener in self.listeners:
            listener(msg)

    def _send(self, frames: list[tuple[int, bytes]]) -> None:
        send_data = self._send_data
        for frame_id, data in frames:
            if send_data is not None:
                send_data(frame_id, data)
            else:
                self.bus.send(data_frame(frame_id, data))
            self.sent += 1

    def handle(self, msg: can.Message, now: float) -> bool:
        """Take one frame; a SIM_SYNC tick is answered at once (lock-step). True if the frame was the plant's
        (even a duplicate or a rejected one: the plant is alive), False for others (e.g. our own, looped back).

        In lock-step, time is the plant's: frames arriving before a tick belong to it (tick time = the previous
        tick's + one cycle), so validity and controller time never depend on the wall clock."""
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id or msg.is_fd:
            status, _ = self.rx.take(msg, now)  # not ours, or one of ours as a CAN FD frame: rejected
            return status != IGNORED
        return self.handle_data(msg.arbitration_id, bytes(msg.data), now)

    def handle_data(self, frame_id: int, data: bytes, now: float) -> bool:
        """:meth:`handle` of a classic data frame with an 11-bit ID, given by its ID and data (as the in-process
        bus hands it over)."""
        stamp = self._sim_now + self.cycle if self.lockstep else now
        status, frame = self.rx.take_data(frame_id, data, stamp)
        if status not in (NEW, DUPLICATE):
            return status != IGNORED
        assert frame is not None  # NEW and DUPLICATE come decoded
        if self.heard_plant_at is None:
            self.heard_plant_at = now
        if frame.name != "SIM_SYNC":
            if status == NEW:
                if self.listeners:
                    self._record(frame_id, data, stamp, is_rx=True)
                if self._pending is not None and not self._missing(self._pending):  # its tick came first
                    self._answer_tick(self._pending)
                    self._answered_early = True
            return True
        tick = int(frame.values["Tick"])
        if status == NEW and self.listeners and tick != SYNC_PROBE:
            self._record(frame_id, data, stamp, is_rx=True)
        if tick == SYNC_PROBE:
            if self._answered != SYNC_PROBE:
                self._reset_for_lockstep()
            self.rx.states["SIM_SYNC"].forget()  # the plant's ticks restart their counter after the handshake
        if tick == self._answered:  # a repeated tick (its answer was lost or late): the same frames again
            if self._answered_early:  # the tick of a re-sent period whose frame just completed it: answered
                self._answered_early = False
                return True
            self.answers_resent += self._answer_sends > 0
            self._answer_sends += 1
            self._send(self._answer)
            return True
        if self._answered not in (None, SYNC_PROBE) and tick < self._answered:
            return True  # a repeat of an older tick: answered long ago
        if status == DUPLICATE and tick != self._pending:
            return True
        if self._answered is not None and not self._complete(tick):
            return True  # answered when the missing frames come (late, or with the plant's re-send)
        self._answer_tick(tick)
        return True

    def _answer_tick(self, tick: int) -> None:
        """Run the control step of ``tick`` and send its answer (kept for the tick's repeats)."""
        self._pending, self._answered_early = None, False
        self._sim_now = tick * self.cycle
        if not self.lockstep:
            log.info("SIM_SYNC seen: lock-step, answering each tick")
            self.lockstep = True
            self.controller = type(self.controller)(self.controller.cal)  # time base: the plant's from now on
            self.tx.next_due = {name: self._sim_now for name in self.tx.next_due}
            for state in self.rx.states.values():
                if state.last_time is not None:
                    state.last_time = self._sim_now
        self._answer = self.control(self._sim_now, echo=tick & 0xFF)
        self._answered, self._answer_sends = tick, 1

    def _missing(self, tick: int) -> list[str]:
        """The plant messages due at ``tick`` (each on its DBC cycle from tick 0) not yet taken in its period."""
        t = tick * self.cycle
        return [name for name, every in self._due_every.items() if tick % every == 0
                and ((last := self.rx.states[name].last_time) is None or abs(last - t) > 1e-9)]

    def _complete(self, tick: int) -> bool:
        """Whether every plant frame due at ``tick`` came in its period; if not, whether the tick has been seen
        ``SIGHTS_BEFORE_INCOMPLETE`` times (then it is answered anyway, and counted). An incomplete tick stays
        pending: the frame that completes it (one delivered after the tick, or the plant's re-send) answers it."""
        self._pending_sights = self._pending_sights + 1 if tick == self._pending else 1
        self._pending = tick
        missing = self._missing(tick)
        if not missing:
            self._pending = None
            return True
        if self._pending_sights < SIGHTS_BEFORE_INCOMPLETE:
            log.info("tick %d: %s missing, waiting for it (late, or re-sent)", tick, ", ".join(missing))
            return False
        log.warning("tick %d seen %d times without %s: answered with the last values", tick, self._pending_sights,
                    ", ".join(missing))
        self.incomplete_answers += 1
        self._pending = None
        return True

    def _reset_for_lockstep(self) -> None:
        """Prepare the answer to the plant's presence probe from a clean state, so every run starts alike.
        Repeated probes (the plant probes every 0.2 s until it hears the answer) get the same answer, byte for
        byte: the counters restart once, and the tick-0 answer follows the probe answer's counter."""
        log.info("lock-step presence probe: reset and answer")
        self.lockstep = True
        self.controller = type(self.controller)(self.controller.cal)
        self.rx = RxMonitor(self.codec, list(TCU_RX))
        self.tx = TxScheduler(self.codec, list(TCU_TX))
        self._answer = [(self.tx.ids["TCU_CMD"], self.tx.data("TCU_CMD", {"SyncEcho": SYNC_PROBE & 0xFF}))]
        self._answered, self._answer_sends = SYNC_PROBE, 0
        self._pending, self._pending_sights, self._answered_early = None, 0, False
        self._sim_now = self.now = -self.cycle  # the next tick is tick 0

    def frame_counts(self) -> dict:
        """What the TCU heard and sent: totals and, per message it reads, received, rejected by cause, lost
        (counter gaps) and duplicates."""
        rx = self.rx.counts()
        return {"sent": self.sent, "answers_resent": self.answers_resent,
                "incomplete_answers": self.incomplete_answers, "received": self.rx.received,
                "rejected": self.rx.rejected_total, "lost": sum(m["lost"] for m in rx.values()),
                "duplicates": sum(m["duplicates"] for m in rx.values()), "by_message": rx}

    def free_running(self, now: float) -> bool:
        """True once the plant has been heard for a while without a tick: a real-time plant."""
        return (not self.lockstep and self.heard_plant_at is not None
                and now - self.heard_plant_at > SYNC_WAIT_S)

    def pump(self) -> None:
        """Handle every frame already waiting (for an in-process peer on python-can's virtual bus)."""
        recv = self._recv_data or self.bus.recv
        while (item := recv(0.0)) is not None:
            if isinstance(item, tuple):
                self.handle_data(item[0], item[1], self._sim_now)
            else:
                self.handle(item, self._sim_now)

    def run(self, duration: float | None = None, clock: Callable[[], float] = time.monotonic,
            idle_timeout: float | None = None, should_stop: Callable[[], bool] = lambda: False) -> None:
        """Serve the bus until ``duration`` [s] has passed (None: forever), ``should_stop()`` is true, or the plant
        has been silent for ``idle_timeout`` seconds after having been heard."""
        start = clock()
        next_cycle = start
        last_heard = start
        while (duration is None or clock() - start < duration) and not should_stop():
            now = clock()
            free = self.free_running(now - start)
            msg = self.bus.recv(timeout=max(0.0, next_cycle - now) if free else 0.05)
            now = clock()
            if msg is not None and self.handle(msg, now - start):
                last_heard = now
            if idle_timeout is not None and self.heard_plant_at is not None and now - last_heard > idle_timeout:
                log.info("plant silent for %.1f s: stopping", idle_timeout)
                return
            if not self.free_running(now - start):
                next_cycle = now
            elif now >= next_cycle:
                for _ in range(DRAIN_MAX):  # what waits first: a starved TCU controls on the newest frames
                    if (queued := self.bus.recv(timeout=0.0)) is None:
                        break
                    if self.handle(queued, (now := clock()) - start):
                        last_heard = now
                self.control(now - start)
                next_cycle += self.cycle
                if next_cycle <= now:  # fell behind: skip, keep the grid
                    next_cycle += ((now - next_cycle) // self.cycle + 1) * self.cycle
                    if next_cycle <= now:  # the division rounded a whole cycle down: the next is strictly later
                        next_cycle += self.cycle
