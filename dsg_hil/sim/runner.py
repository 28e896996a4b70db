"""The plant process: owns the bus and the clock, steps the plant, sends its frames, takes the TCU's commands.

* Lock-step (``run_lockstep``): the plant is the time master. Each control period (the TCU_CMD cycle time of the
  DBC) it sends the frames that are due and a SIM_SYNC tick, waits for the TCU_CMD whose SyncEcho answers that
  tick, and advances. A late answer makes it re-send the period's frames, byte for byte (the TCU answers a
  repeated tick with the frames it already sent); retransmissions and duplicates are counted, never logged, so
  a run that needed them logs the same frames as one that did not. Frame timestamps are simulated time, so the
  same scenario gives the same frames, bit for bit. A TCU silent for the reply timeout ends the run (PeerLost).
* Real time (``run_realtime``): the plant steps at its fixed step paced by a monotonic clock against absolute
  deadlines, sends each frame at its DBC cycle time, and uses commands as they arrive.

In both, a command that is missing for 3 cycle times (frames failing their counter or CRC check count as missing)
puts the hydraulics in their unpowered default (commanded pressure 0: the pressures decay, return springs open
the clutches); the event is counted and logged, and control resumes with the next valid command.
"""

from __future__ import annotations

import logging
import time
from collections import Counter as Tally
from collections.abc import Callable, Iterable

import can
import numpy as np

from ..physics.friction import RAD_S_TO_RPM
from ..physics.plant import N_OUT, Plant, PlantInputs, PlantOutputs
from .plant_io import PLANT_RX, PLANT_TX, PLANT_USES, SYNC, SYNC_PROBE, plant_signals
from ..protocol import Codec, DecodedFrame, RxMonitor, TxScheduler
from ..common.errors import PeerLost, PeerTimeout  # defined with the other errors, importable here
from ..protocol.faults import FaultInjector, FaultSpec, fault_counts, with_faults
from ..protocol.frame import data_frame
from ..protocol.validity import IGNORED, NEW, REJECTED, TIMEOUT_CYCLES
from .scenario import DriverInput, Scenario
from ..results.summary import RunSummary

log = logging.getLogger(__name__)


RETRY_FIRST_S = 0.1  # lock-step: wall-clock wait for a tick's answer before the first re-send [s]
RETRY_MAX_S = 1.0  # ... the wait doubles after each re-send up to this [s]
RETRIES_PER_TICK = 6  # ... re-sends before the tick is given up (0.1+0.2+0.4+0.8+1+1+1 = 4.5 s in all)
STATUS_RETRIES = 2  # ... re-sends for a TCU_STATUS missing from an answer, before going on without it


class PlantRunner:
    def __init__(self, plant: Plant, scenario: Scenario, codec: Codec, bus: can.BusABC,
                 listeners: tuple[Callable[[can.Message], None], ...] = (),
                 progress: Callable[[str], None] | None = None) -> None:
        for name in PLANT_USES:  # resolved at start-up by the codec; fail here if not
            codec.message(name)
        self.plant, self.scenario, self.codec, self.bus = plant, scenario, codec, bus
        self.listeners = listeners
        self.progress = progress
        self.period = codec.cycle_time("TCU_CMD")
        self.steps_per_period = max(1, round(self.period / plant.dt))
        self.tx = TxScheduler(codec, list(PLANT_TX))
        self.sync = TxScheduler(codec, [SYNC])
        self.rx = RxMonitor(codec, list(PLANT_RX))
        self.summary = RunSummary(plant.dt)
        self.out: PlantOutputs = plant.outputs()
        self.command_valid = False
        self.P_cmd = (0.0, 0.0)
        self.tick = 0
        self.sent = 0
        self.sent_by: Tally[str] = Tally()  # frames sent (first transmissions, the ones logged)
        self.retries: Tally[str] = Tally()  # lock-step re-sends (not logged)
        self.unanswered_ticks = 0
        self._given_up = 0  # lock-step: ticks given up in a row just before this one (their answers may come late)
        self.probes = 0  # lock-step presence probes sent before tick 0 (not logged)
        self.retry_first_s, self.retry_max_s, self.retries_per_tick = RETRY_FIRST_S, RETRY_MAX_S, RETRIES_PER_TICK
        self._names = {codec.frame_id(name): name for name in PLANT_USES}
        self._cmd_id, self._sync_id = codec.frame_id("TCU_CMD"), codec.frame_id(SYNC)
        self._status_every = round(codec.cycle_time("TCU_STATUS") / self.period)  # in control periods
        self._period: list[tuple[int, bytes, float]] = []  # lock-step: this period's frames, for re-sending
        self._held: list[can.Message] | None = None  # lock-step: frames taken, logged when the answer is complete
        self._send_data: Callable[[int, bytes], None] | None = None  # see _bind_bus
        self._recv_data: Callable[[float], tuple[int, bytes] | can.Message | None] | None = None
        self._silent_s = 0.0  # lock-step: wall time waited in vain on ticks given up since the TCU was last heard
        self._cmd_on_bus: float | None = None
        self._traces: dict[int, np.ndarray] = {}  # by number of steps: the plant's trace of a period (_advance)
        self._running = False  # set once the run proper starts (after the lock-step handshake)
        self.injectors: dict[str, FaultInjector | None] = {}  # by side, see ``inject``
        self.fault_seed = 0
        self.faults_in_tcu: list[str] = []  # faults passed on to a TCU process, which counts them itself
        self._bind_bus()

    def _bind_bus(self) -> None:
        """Frames as (ID, data), no :class:`can.Message` built unless a listener wants one, where the bus is the
        direct in-process one (:class:`~dsg_hil.protocol.local.LocalBus`, unwrapped: no plant-side faults)."""
        self._send_data = getattr(self.bus, "send_data", None)
        self._recv_data = getattr(self.bus, "recv_data", None)
        self._channel = getattr(self.bus, "channel", None)  # of the frames received as (ID, data), when logged

    def clock(self) -> float:
        """The plant's time for the frames it sends (fault windows): simulated time, which is run time in real
        time; -1 before the run starts, so the lock-step handshake is never faulted."""
        return round(self.plant.state.t, 9) if self._running else -1.0

    def inject(self, specs: Iterable[FaultSpec], seed: int = 0) -> None:
        """Send the plant's frames through an injector of ``specs`` (plant-side faults), on the plant's clock."""
        self.bus, self.injectors["plant"] = with_faults(self.bus, self.codec.db, specs, seed, self.clock)
        self.fault_seed = seed
        self._bind_bus()

    def fault_summary(self) -> dict:
        """The summary's ``faults``: frames each fault hit (re-sends included), by side and in all; and those
        passed on to a TCU process (``in_tcu_process``: counted in its output)."""
        counts = fault_counts(self.injectors, self.fault_seed)
        if self.faults_in_tcu:
            counts["in_tcu_process"] = self.faults_in_tcu
        return counts

    # ---- frames --------------------------------------------------------------------------------------------
    def _send(self, frame_id: int, data: bytes, stamp: float) -> can.Message | None:
        """Put a frame on the bus; returns its message, None if none was built (see ``_bind_bus``)."""
        if self._send_data is not None:
            self._send_data(frame_id, data)
            return None
        msg = data_frame(frame_id, data, stamp)
        self.bus.send(msg)
        return msg

    def _emit(self, frame_id: int, data: bytes, stamp: float) -> None:
        """Send a frame of this period (a first transmission: counted, kept for re-sending, logged)."""
        msg = self._send(frame_id, data, stamp)
        self.sent += 1
        self.sent_by[self._names[frame_id]] += 1
        self._period.append((frame_id, data, stamp))
        if self.listeners:
            if msg is None:
                msg = data_frame(frame_id, data, stamp)
            for listener in self.listeners:
                listener(msg)

    def _log(self, msg: can.Message) -> None:
        for listener in self.listeners:
            listener(msg)

    def _publish_due(self, t: float, stamp: float) -> None:
        names = self.tx.due(t)
        if not names:  # real time: most 1-ms steps send nothing, so build no signal values for them
            return
        values = plant_signals(self.out, self.scenario.driver_at(t))
        data, ids = self.tx.data, self.tx.ids
        for name in names:
            self._emit(ids[name], data(name, values[name]), stamp)

    def _take(self, msg: can.Message, now: float, stamp: float) -> tuple[str, DecodedFrame | None]:
        """Handle one received frame: (status, frame) as :meth:`RxMonitor.take`; only new frames are used and
        logged."""
        status, frame = self.rx.take(msg, now)
        if status != NEW:
            return status, frame
        assert frame is not None  # a NEW frame comes decoded
        msg.timestamp = stamp
        self._use(frame, msg)
        return status, frame

    def _take_data(self, frame_id: int, data: bytes, now: float, stamp: float) -> tuple[str, DecodedFrame | None]:
        """:meth:`_take` of a frame received as (ID, data) from the in-process bus (see ``_bind_bus``)."""
        status, frame = self.rx.take_data(frame_id, data, now)
        if status == NEW:
            assert frame is not None  # a NEW frame comes decoded
            self._use(frame, data_frame(frame_id, data, stamp, self._channel, True) if self.listeners else None)
        return status, frame

    def _use(self, frame: DecodedFrame, msg: can.Message | None) -> None:
        """A new frame from the TCU: logged (``msg``: None with no listeners), its values used."""
        if msg is not None and self.listeners:
            if self._held is not None:
                self._held.append(msg)
            else:
                self._log(msg)
        if frame.name == "TCU_CMD":
            self.P_cmd = (frame.values["P_CL_Cmd"] * 1e6, frame.values["P_CH_Cmd"] * 1e6)
        elif frame.name == "TCU_STATUS":
            self.summary.on_status(self.plant.state.t, frame.values, self.out)

    def _check_command(self, now: float) -> None:
        valid = self.rx.valid("TCU_CMD", now)
        if self.command_valid and not valid:
            self.summary.fallback_events += 1
            log.warning("t=%.3f s: TCU_CMD missing for %.0f ms: hydraulics unpowered (pressures decay to 0)",
                        self.plant.state.t, 1000 * self.rx.states["TCU_CMD"].deadline)
        elif valid and not self.command_valid and self.summary.fallback_events:
            log.warning("t=%.3f s: valid TCU_CMD again: control resumes", self.plant.state.t)
        self.command_valid = valid

    # ---- physics -------------------------------------------------------------------------------------------
    def _inputs(self, driver: DriverInput, now: float) -> PlantInputs:
        """Plant inputs from the driver and the TCU's frames; ``now`` is the time frames are judged on."""
        status = self.rx.states["TCU_STATUS"]
        brake_request = status.values.get("BrakeRequest", 0.0) if status.valid(now) else 0.0
        P_CL, P_CH = self.P_cmd if self.command_valid else (0.0, 0.0)
        engine = None if self.scenario.engine_speed_rpm is None else self.scenario.engine_speed_rpm / RAD_S_TO_RPM
        return PlantInputs(P_CL_cmd=P_CL, P_CH_cmd=P_CH, brake=max(driver.brake, brake_request),
                           grade=self.scenario.grade_rad, engine_speed_request=engine)

    def _advance(self, steps: int, now: float) -> None:
        """``steps`` plant steps on one set of inputs: one compiled call, whose trace (every step's outputs) feeds
        the summary as an array; a single step (real time) goes the per-sample way, cheaper for one row."""
        driver = self.scenario.driver_at(self.plant.state.t)
        inputs = self._inputs(driver, now)
        creeping, fallback, desired = driver.creep_request, not self.command_valid, driver.desired_speed_mps
        if steps == 1:
            self.out = self.plant.step(inputs)
            self.summary.on_step(self.out, creeping, fallback, desired)
            return
        trace = self._traces.get(steps)
        if trace is None:
            trace = self._traces[steps] = np.empty((steps, N_OUT))
        self.out = self.plant.advance(inputs, steps, trace)
        self.summary.on_period(trace, PlantOutputs._fields, Plant.sample, creeping, fallback, desired)

    def _report(self, every_s: float = 10.0) -> None:
        t = self.plant.state.t
        if self.progress and int(t / every_s) != int((t - self.period) / every_s):
            o, s = self.out, self.summary
            self.progress(f"t={t:7.1f}/{self.scenario.duration_s:g} s  v={o.v:5.2f} m/s  T_CL={o.T_CL:6.1f}  "
                          f"T_CH={o.T_CH:6.1f} degC  P_CL={o.P_CL / 1e6:4.2f}  P_CH={o.P_CH / 1e6:4.2f} MPa  "
                          f"TCU {s.tcu_state}/{s.active_clutch}")

    @property
    def n_periods(self) -> int:
        return int(round(self.scenario.duration_s / self.period))

    # ---- lock-step ------------------------------------------------------------------------------------------
    def run_lockstep(self, reply_timeout: float = 5.0, pump: Callable[[], None] | None = None,
                     startup_timeout: float = 60.0) -> RunSummary:
        """Run the scenario in lock-step. ``pump`` lets an in-process TCU answer (python-can ``virtual``).

        First a presence handshake (not logged): a SIM_SYNC probe every 0.2 s until the TCU answers, which
        resets it; so the run starts from the same state whenever the TCU came up, and no tick is lost to a TCU
        still starting. Then each tick is re-sent while its answer is late (see ``_await_answer``); a TCU silent
        for ``reply_timeout`` wall-clock seconds ends the run with :class:`PeerLost` (stop reason
        ``peer_lost``), the summary being valid up to that point. Compiled code is loaded before the handshake:
        once the TCU has answered, a pause of seconds (numba's cache loaded under emulation) would look to it
        like a plant gone."""
        self.summary.creep.prepare()
        self._handshake(startup_timeout, pump)
        self.rx.require("TCU_CMD", "echo", self._answers_tick)
        self._running = True
        t0 = time.monotonic()
        try:
            for self.tick in range(self.n_periods):  # noqa: B020 - the tick is kept on self on purpose
                t = self.tick * self.period
                self._period.clear()
                self._publish_due(t, stamp=t)
                self._emit(self._sync_id, self.sync.data(SYNC, {"Tick": self.tick}), t)
                if pump is not None:
                    pump()
                answered = self._await_answer(t, reply_timeout, pump)
                self._given_up = 0 if answered else self._given_up + 1
                if not answered:
                    self.unanswered_ticks += 1
                    log.warning("t=%.2f s: lock-step tick %d unanswered after %d re-sends: the period runs on the "
                                "last command while it is valid (DBC: 3 cycle times), then unpowered",
                                t, self.tick, self.retries_per_tick)
                self._check_command(t)
                self._advance(self.steps_per_period, t)
                self._report()
        finally:
            self.summary.wall_time_s = time.monotonic() - t0
        return self.summary

    def _handshake(self, timeout: float, pump: Callable[[], None] | None) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.bus.send(self.sync.frame(SYNC, {"Tick": SYNC_PROBE}))
            self.probes += 1
            if pump is not None:
                pump()
            probe_end = min(deadline, time.monotonic() + 0.2)
            while (remaining := probe_end - time.monotonic()) > 0:
                msg = self.bus.recv(timeout=remaining)
                frame = None if msg is None else self.rx.receive(msg, 0.0)
                if msg is not None and frame is not None and frame.name == "TCU_CMD" \
                        and int(frame.values["SyncEcho"]) == SYNC_PROBE & 0xFF:
                    self.rx = RxMonitor(self.codec, list(PLANT_RX))  # the run starts from clean counts,
                    self.rx.prime(msg)  # its counters following the answer (a repeat of it is a duplicate)
                    self.sync = TxScheduler(self.codec, [SYNC])
                    return
        raise PeerTimeout(f"no TCU answered the lock-step presence probe within {timeout:g} s: is the TCU "
                          f"(ecu-stub) running on the same bus?")

    def _answers_tick(self, frame: DecodedFrame) -> str | None:
        """Lock-step: a TCU_CMD is taken only as the answer to the present tick (its SyncEcho the tick's low byte)
        or, late, to one of the ticks given up just before it (at most as many as a command stays valid, 3 cycle
        times); another (an old answer, a random frame that passed CRC and counter) is rejected ("echo")."""
        echo = int(frame.values["SyncEcho"])
        late = (self.tick - echo) % 256
        if late == 0 or late <= min(self._given_up, int(TIMEOUT_CYCLES)):
            return None
        return f"SyncEcho {echo} answers no tick waiting (tick {self.tick})"

    def _await_answer(self, t: float, reply_timeout: float, pump: Callable[[], None] | None) -> bool:
        """Wait for the answer to this tick: the TCU_CMD whose SyncEcho is the tick's (see ``_answers_tick`` for
        the others), after the TCU_STATUS when one is expected (see ``_status_expected``); True when the command
        came.

        While it is late the period's frames (tick included) are re-sent, byte for byte and not logged, after
        ``retry_first_s`` and then at doubling intervals up to ``retry_max_s``; at once when a TCU_CMD is
        rejected or comes without its TCU_STATUS (then ``STATUS_RETRIES`` times at most). The TCU answers a
        repeated tick with the frames it already sent. After ``retries_per_tick`` re-sends the tick is given up
        (False). Nothing at all from the TCU for ``reply_timeout`` seconds of waiting (summed over ticks given
        up; the plant's own time between waits does not count, nor does a stall of the plant: what arrived
        meanwhile is read first): PeerLost. The answer's frames are logged when it is complete, TCU_CMD last,
        as the TCU sends them, whatever retries brought them."""
        cmd_id = self._cmd_id
        recv = self._recv_data or self.bus.recv
        retries, interval = 0, self.retry_first_s
        since = time.monotonic()  # silence is counted from here, plus ``_silent_s`` of ticks given up
        next_retry = since + interval
        have_cmd, status_retries = False, 0
        self._held = []
        try:
            while True:
                lost_at = since + reply_timeout - self._silent_s
                msg = recv(max(0.0, min(next_retry, lost_at) - time.monotonic()))
                if msg is not None:
                    if isinstance(msg, tuple):
                        frame_id = msg[0]
                        status, frame = self._take_data(frame_id, msg[1], t, stamp=t)
                    else:
                        frame_id = msg.arbitration_id
                        status, frame = self._take(msg, t, stamp=t)
                    if status != IGNORED:
                        since, self._silent_s = time.monotonic(), 0.0
                    if status == REJECTED and frame_id == cmd_id and not have_cmd:
                        next_retry = time.monotonic()  # a command that failed its checks: ask again at once
                    elif status == NEW and frame is not None and frame.name == "TCU_CMD" \
                            and int(frame.values["SyncEcho"]) == self.tick & 0xFF:
                        have_cmd = True
                        if not self._status_expected(t):
                            return True
                        next_retry = time.monotonic()  # its TCU_STATUS was lost: ask again at once
                    elif status == NEW and frame is not None and frame.name == "TCU_STATUS" and have_cmd:
                        return True
                    continue
                now = time.monotonic()
                if now >= lost_at:
                    self.summary.stop_reason = "peer_lost"
                    raise PeerLost(f"TCU silent for {reply_timeout:g} s at lock-step tick {self.tick} (t={t:.2f} "
                                   f"s): peer lost; the run ends here")
                if now >= next_retry:
                    if have_cmd and status_retries == STATUS_RETRIES:
                        log.info("t=%.2f s: TCU_STATUS missing from the answer to tick %d", t, self.tick)
                        return True
                    if retries == self.retries_per_tick:
                        self._silent_s += now - since
                        return have_cmd
                    self._resend_period()
                    retries += 1
                    status_retries += have_cmd
                    interval = min(2.0 * interval, self.retry_max_s)
                    next_retry = now + interval
                    if pump is not None:
                        pump()
        finally:
            if self._held:
                for msg in sorted(self._held, key=lambda m: m.arbitration_id == cmd_id):
                    self._log(msg)
            self._held = None

    def _status_expected(self, t: float) -> bool:
        """Whether this tick's answer should hold a TCU_STATUS: due now on its DBC cycle from tick 0, as the last
        one due came (so a TCU sending it on a schedule of its own costs no retries after tick 0)."""
        every = self._status_every
        state = self.rx.states["TCU_STATUS"]
        if self.tick % every or (state.last_time is not None and abs(state.last_time - t) < 1e-9):
            return False
        previous = t - every * self.period
        return self.tick == 0 or (state.last_time is not None and abs(state.last_time - previous) < 1e-9)

    def _resend_period(self) -> None:
        for frame_id, data, stamp in self._period:
            self._send(frame_id, data, stamp)
            self.retries[self._names[frame_id]] += 1

    # ---- real time ------------------------------------------------------------------------------------------
    def run_realtime(self, clock: Callable[[], float] = time.monotonic) -> RunSummary:
        """Run the scenario paced by ``clock``: one plant step per ``dt`` against absolute deadlines.

        Command validity is judged on the clock (a dead TCU is dead in wall time); a machine too slow to keep
        up makes the run late, which is counted and reported as ``realtime_factor``."""
        start = clock()
        self._running = True
        dt = self.plant.dt
        n_steps = int(round(self.scenario.duration_s / dt))
        for k in range(n_steps):
            t = k * dt
            self._publish_due(t, stamp=start + t)
            deadline = start + (k + 1) * dt
            while (msg := self.bus.recv(timeout=max(deadline - clock(), 0.0))) is not None:
                on_bus = msg.timestamp  # until this step's deadline: take what arrives
                status, frame = self._take(msg, clock() - start, stamp=start + t)
                if status == NEW and frame is not None and frame.name == "TCU_CMD":
                    self._cmd_on_bus = on_bus
            now = clock() - start
            self._check_command(now)
            if self._cmd_on_bus is not None:  # the newest command is used from this step on
                latency = time.time() - self._cmd_on_bus
                if 0.0 <= latency < 1.0:  # bus timestamps are wall-clock (socketcan, virtual)
                    self.summary.command_latency_s.append(latency)
                self._cmd_on_bus = None
            self._advance(1, now)
            self._period.clear()  # (re-sent in lock-step only)
            if k % self.steps_per_period == 0:
                self._report()
        wall = self.summary.wall_time_s = clock() - start
        self.summary.realtime_factor = self.scenario.duration_s / wall if wall > 0 else None
        if self.summary.realtime_factor is not None and self.summary.realtime_factor < 0.95:
            log.warning("real time: %.1f simulated s took %.1f s (%.0f %% of real time): machine too slow",
                        self.scenario.duration_s, wall, 100 * self.summary.realtime_factor)
        return self.summary

    def frames(self) -> dict:
        """Frame counts for the summary: totals (``sent`` counts first transmissions, the frames logged) and per
        message: sent, retries (lock-step re-sends), received (every frame of it heard), taken, rejected by
        cause, lost (counter gaps), duplicates (repeats ignored); ``unanswered_ticks``: lock-step periods run
        without their answer; ``probes``: lock-step presence probes it took to find the TCU."""
        rx = self.rx.counts()
        by_message = {}
        for name in PLANT_USES:
            got = rx.get(name, {"received": 0, "taken": 0, "rejected": {}, "lost": 0, "duplicates": 0})
            by_message[name] = {"sent": self.sent_by[name], "retries": self.retries[name], **got}
        return {"sent": self.sent, "received": self.rx.received, "rejected": self.rx.rejected_total,
                "retries": sum(self.retries.values()), "lost": sum(m["lost"] for m in rx.values()),
                "duplicates": sum(m["duplicates"] for m in rx.values()), "unanswered_ticks": self.unanswered_ticks,
                "probes": self.probes, "by_message": by_message}
