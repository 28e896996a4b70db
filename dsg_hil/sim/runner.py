"""The plant process: owns the bus and the clock, steps the plant, sends its frames, takes the TCU's commands.

* Lock-step (``run_lockstep``): the plant is the time master. Each control period (the TCU_CMD cycle time of the
  DBC) it sends the frames that are due and a SIM_SYNC tick, waits for the TCU_CMD whose SyncEcho answers that
  tick, and advances; the protocol (handshake, answer wait, re-sends) is its master end,
  :class:`~dsg_hil.protocol.lockstep.LockstepMaster`. A late answer makes it re-send the period's frames, byte
  for byte (the TCU answers a repeated tick with the frames it already sent); retransmissions and duplicates are
  counted, never logged, so a run that needed them logs the same frames as one that did not. Frame timestamps
  are simulated time, so the same scenario gives the same frames, bit for bit. A TCU silent for the reply
  timeout over 3 ticks in a row ends the run (PeerLost).
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
from collections.abc import Callable, Iterable, Sequence

import can
import numpy as np

from ..common.units import CV
from ..physics.plant import N_OUT, Plant, PlantInputs, PlantOutputs
from ..physics.powertrain import brake_for_decel
from .plant_io import SHIPPED, PlantIO
from ..protocol import Codec, DecodedFrame, RxMonitor, TxScheduler
from ..protocol.faults import FaultInjector, FaultSpec, fault_counts, with_faults
from ..protocol.frame import FrameListener, data_frame
from ..protocol.lockstep import LockstepMaster, PeerLost, PeerTimeout, Received
from ..protocol.validity import NEW, NS_PER_MS, NS_PER_S
from .scenario import DriverInput, Scenario
from ..results.summary import RunSummary

log = logging.getLogger(__name__)


__all__ = ["PeerLost", "PeerTimeout", "PlantRunner"]  # the errors (common.errors) importable here, as before


class PlantRunner:
    def __init__(self, plant: Plant, scenario: Scenario, codec: Codec, bus: can.BusABC,
                 listeners: Sequence[FrameListener] = (),
                 progress: Callable[[str], None] | None = None, io: PlantIO | None = None) -> None:
        self.io = io = io if io is not None else SHIPPED  # the messages and signals (a binding's)
        for name in io.uses:  # resolved at start-up by the codec; fail here if not
            codec.message(name)
        self._cmd_name, self._status_name = io.command, io.status
        self.plant, self.scenario, self.codec, self.bus = plant, scenario, codec, bus
        self.on_tick: Callable[[], object] | None = None  # lock-step: called as each tick is sent (RunConfig.on_period)
        self.listeners = tuple(listeners)
        self.progress = progress
        self.period = codec.cycle_time(io.command)
        self.period_ms = codec.cycle_time_ms(io.command)
        self.steps_per_period = max(1, round(self.period_ms * NS_PER_MS / plant.dt_ns))
        self.tx = TxScheduler(codec, list(io.tx))
        self._frame_data = {name: io.frame_encoder(codec, name) for name in io.tx}  # (out, driver, counter) -> data
        self.summary = RunSummary(plant.dt)
        self.out: PlantOutputs = plant.outputs()
        self.command_valid = False
        self.P_cmd = (0.0, 0.0)
        self.decel_cmd = 0.0  # TCU_CMD.DecelRequest [m/s^2]: the brakes' deceleration, while the command is valid
        self.sent = 0
        self._fd: dict[int, bool] = codec.fd  # the CAN FD messages' IDs: their frames built as CAN FD
        self._names = {codec.frame_id(name): name for name in io.uses}
        self._sent_by_id = dict.fromkeys(self._names, 0)  # frames sent (first transmissions, the ones logged)
        self._send_data: Callable[[int, bytes], None] | None = None  # see _bind_bus
        self._send_all: Callable[[list[tuple[int, bytes]]], None] | None = None  # ... (a batch of send_data)
        self.link = LockstepMaster(codec, io.rx, self._send, bus.recv, self._use_stamped,
                                   names=(io.sync, io.tick, io.command, io.echo, io.status))  # lock-step protocol
        self._keep: Callable[[int, bytes, float], None] | None = None  # lock-step: the period's frames, re-sent
        self._cmd_on_bus: float | None = None
        self._checked_at = 0.0  # when TCU_CMD's validity was last checked (_check_command)
        self._held: PlantInputs | None = None  # the last inputs (_inputs)
        self._traces: dict[int, np.ndarray] = {}  # by number of steps: the plant's trace of a period (_advance)
        self._driver_braking = False  # the driver's pedal above 0 in the last period (_advance; the summary's)
        self._running = False  # set once the run proper starts (after the lock-step handshake)
        self._wall0 = time.monotonic()  # when it did (wall clock: the progress line's pace and ETA)
        self.injectors: dict[str, FaultInjector | None] = {}  # by side, see ``inject``
        self.fault_seed = 0
        self.faults_in_tcu: list[str] = []  # faults passed on to a TCU process, which counts them itself
        self._bind_bus()

    # the lock-step's state, kept by its master (``link``); ``rx`` also serves real time
    @property
    def rx(self) -> RxMonitor:
        return self.link.rx

    @property
    def tick(self) -> int:
        return self.link.tick

    @property
    def probes(self) -> int:
        return self.link.probes

    @property
    def unanswered_ticks(self) -> int:
        return self.link.unanswered_ticks

    @property
    def retries(self) -> Tally[str]:
        """Lock-step re-sends (not logged), by message."""
        return Tally({self._names[frame_id]: n for frame_id, n in self.link.retries.items()})

    @property
    def retry_first_s(self) -> float:
        return self.link.retry_first_s

    @retry_first_s.setter
    def retry_first_s(self, value: float) -> None:
        self.link.retry_first_s = value

    @property
    def retry_max_s(self) -> float:
        return self.link.retry_max_s

    @retry_max_s.setter
    def retry_max_s(self, value: float) -> None:
        self.link.retry_max_s = value

    @property
    def retries_per_tick(self) -> int:
        return self.link.retries_per_tick

    @retries_per_tick.setter
    def retries_per_tick(self, value: int) -> None:
        self.link.retries_per_tick = value

    def _bind_bus(self) -> None:
        """Frames as (ID, data), no :class:`can.Message` built unless a listener wants one, where the bus is the
        direct in-process one (:class:`~dsg_hil.protocol.local.LocalBus`, unwrapped: no plant-side faults)."""
        self._send_data = getattr(self.bus, "send_data", None)
        self._send_all = getattr(self.bus, "send_all", None) if self._send_data is not None else None
        self.link.recv = getattr(self.bus, "recv_data", None) or self.bus.recv
        self._channel = getattr(self.bus, "channel", None)  # of the frames received as (ID, data), when logged

    def clock(self) -> float:
        """The plant's time for the frames it sends (fault windows): simulated time, which is run time in real
        time (its step count in seconds, the exact float of a whole number of ns: a window's start_s from a
        scenario compares exactly); -1 before the run starts, so the lock-step handshake is never faulted."""
        return self.plant.state.t if self._running else -1.0

    def inject(self, specs: Iterable[FaultSpec], seed: int = 0) -> None:
        """Send the plant's frames through an injector of ``specs`` (plant-side faults), on the plant's clock; a
        frame it changes is sealed again with its message's protection (the codec's: a binding's profile)."""
        self.bus, self.injectors["plant"] = with_faults(self.bus, self.codec.db, specs, seed, self.clock,
                                                        self.codec.protections())
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
        msg = data_frame(frame_id, data, stamp, fd=self._fd)
        self.bus.send(msg)
        return msg

    @property
    def sent_by(self) -> Tally[str]:
        """Frames sent (first transmissions, the ones logged), by message."""
        return Tally({self._names[frame_id]: n for frame_id, n in self._sent_by_id.items() if n})

    def _emit(self, frame_id: int, data: bytes, stamp: float) -> None:
        """Send a frame of this period (a first transmission: counted, kept for re-sending, logged)."""
        if self._send_data is not None:  # _send, written out: about six frames every control period
            self._send_data(frame_id, data)
            msg = None
        else:
            msg = self._send(frame_id, data, stamp)
        self.sent += 1
        self._sent_by_id[frame_id] += 1
        if self._keep is not None:
            self._keep(frame_id, data, stamp)
        if self.listeners:
            if msg is None:
                msg = data_frame(frame_id, data, stamp, fd=self._fd)
            for listener in self.listeners:
                listener(msg)

    def _log(self, msg: can.Message) -> None:
        for listener in self.listeners:
            listener(msg)

    def _publish_due(self, now_ms: int, stamp: float) -> None:
        """Send the plant's frames due at ``now_ms`` (the plant's time in whole ms), stamped ``stamp``."""
        names = self.tx.due_ms(now_ms)
        if not names:  # real time: most 1-ms steps send nothing, so build no signal values for them
            return
        out, driver = self.out, self.scenario.driver_at(self.plant.state.t)
        frame_data, ids, next_counter = self._frame_data, self.tx.ids, self.tx.next_counter
        send, keep = self._send_data, self._keep
        if send is None or self.listeners:
            for name in names:  # the messages due alone, each encoded from the outputs directly
                self._emit(ids[name], frame_data[name](out, driver, next_counter(name)), stamp)
            return
        sent_by = self._sent_by_id  # _emit written out for a bus taking (ID, data) and no listener (lock-step)
        for name in names:
            frame_id = ids[name]
            data = frame_data[name](out, driver, next_counter(name))
            send(frame_id, data)
            sent_by[frame_id] += 1
            if keep is not None:
                keep(frame_id, data, stamp)
        self.sent += len(names)

    def _publish_period(self, tick: int, t: float, driver: DriverInput) -> None:
        """Lock-step: send the frames due at ``tick`` (stamped ``t``; ``driver``: the driver's inputs now) and the
        tick's SIM_SYNC last, kept for re-sending: :meth:`_publish_due` and :meth:`_emit` of the tick, in one batch
        on a bus taking them so (the direct in-process bus, no listener)."""
        link, send_all = self.link, self._send_all
        if send_all is None or self.listeners:
            self._publish_due(tick * self.period_ms, stamp=t)
            self._emit(link.sync_id, link.tick_data(), t)
            return
        frames = self.tx.encode_due_ms(tick * self.period_ms, self._frame_data, self.out, driver)
        frames.append((link.sync_id, link.tick_data()))
        send_all(frames)
        link.keep_all(frames, t)
        sent_by = self._sent_by_id
        for frame_id, _ in frames:
            sent_by[frame_id] += 1
        self.sent += len(frames)

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

    def _use_stamped(self, frame: DecodedFrame, item: Received, stamp: float) -> None:
        """:meth:`_use` of a new frame of a lock-step answer (from the master), logged with ``stamp``."""
        if not self.listeners:  # _use, written out: every period
            if frame.name == self._cmd_name:
                self.P_cmd, self.decel_cmd = self.io.commanded_pressures(frame.values), \
                    self.io.commanded_decel(frame.values)
            elif frame.name == self._status_name:
                self.summary.on_status(self.plant.state.t, self.io.status_values(frame.values), self.out)
        elif isinstance(item, tuple):
            self._use(frame, data_frame(item[0], item[1], stamp, self._channel, True, fd=self._fd))
        else:
            item.timestamp = stamp
            self._use(frame, item)

    def _use(self, frame: DecodedFrame, msg: can.Message | None) -> None:
        """A new frame from the TCU: logged (``msg``: None with no listeners), its values used."""
        if msg is not None and self.listeners:
            self._log(msg)
        if frame.name == self._cmd_name:
            io = self.io
            self.P_cmd, self.decel_cmd = io.commanded_pressures(frame.values), io.commanded_decel(frame.values)
        elif frame.name == self._status_name:
            self.summary.on_status(self.plant.state.t, self.io.status_values(frame.values), self.out)

    def _check_command(self, now: float) -> None:
        """Whether TCU_CMD is valid at ``now``, the time frames are judged on (real time: the clock; lock-step:
        the tick); a change is logged, a fallback with the silence it measured and the time since its previous
        check (on a busy machine a check comes late: the silence is the limit plus at most that)."""
        state = self.link.rx.states[self._cmd_name]
        valid = state.valid(now)  # (rx.valid, a look-up less: every period)
        if not valid and not self.command_valid and state.last_time is None and now >= state.deadline \
                and not self.summary.fallback_events:  # never a command by its deadline: a fallback from the start
            self.summary.fallback_events += 1
            log.warning("t=%.3f s: no TCU_CMD in the first %.0f ms: hydraulics unpowered", self.plant.state.t,
                        CV.S_TO_MS * state.deadline)
        elif self.command_valid and not valid:
            self.summary.fallback_events += 1
            silent = now - state.last_time if state.last_time is not None else float("nan")
            log.warning("t=%.3f s: TCU_CMD missing for %.1f ms (limit %.0f ms; previous check %.1f ms before): "
                        "hydraulics unpowered (pressures decay to 0)", self.plant.state.t, CV.S_TO_MS * silent,
                        CV.S_TO_MS * state.deadline, CV.S_TO_MS * (now - self._checked_at))
        elif valid and not self.command_valid and self.summary.fallback_events:
            log.warning("t=%.3f s: valid TCU_CMD again: control resumes", self.plant.state.t)
        self.command_valid = valid
        self._checked_at = now

    # ---- physics -------------------------------------------------------------------------------------------
    def _inputs(self, driver: DriverInput, now: float) -> PlantInputs:
        """Plant inputs from the driver and the TCU's frames; ``now`` is the time frames are judged on. The last
        inputs again when nothing changed (most periods: a held command), else new ones."""
        status = self.link.rx.states[self._status_name]
        brake_request = self.io.brake_request(status.values) if status.valid(now) else 0.0
        P_CL, P_CH = self.P_cmd if self.command_valid else (0.0, 0.0)
        brake = max(driver.brake, brake_request)
        if self.decel_cmd > 0.0 and self.command_valid:  # the brakes as a brake controller takes a deceleration
            brake = max(brake, brake_for_decel(self.decel_cmd, self.plant.params.vehicle))
        held = self._held
        if held is not None and P_CL == held.P_CL_cmd and P_CH == held.P_CH_cmd and brake == held.brake:
            return held  # (grade and engine speed are the scenario's)
        scenario = self.scenario
        rpm = scenario.engine_speed_rpm
        # (P_CL_cmd, P_CH_cmd, brake, grade, engine_speed_request), positional
        self._held = PlantInputs(P_CL, P_CH, brake, scenario.grade_rad, None if rpm is None else rpm / CV.RAD_S_TO_RPM)
        return self._held

    def _advance(self, steps: int, now: float, driver: DriverInput | None = None) -> None:
        """``steps`` plant steps on one set of inputs (``driver``: the driver's inputs now, if known): one compiled
        call, whose trace (every step's outputs) feeds the summary as an array; a single step (real time) goes the
        per-sample way, cheaper for one row."""
        if driver is None:
            driver = self.scenario.driver_at(self.plant.state.t)
        inputs = self._inputs(driver, now)
        creeping, fallback, desired = driver.creep_request, not self.command_valid, driver.desired_speed_mps
        if (driver.brake > 0.0) != self._driver_braking:
            self._driver_braking = not self._driver_braking
            self.summary.on_driver_brake(self._driver_braking)
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
        """A progress line when the last control period crossed a multiple of ``every_s`` (counted in steps), with
        the pace (simulated s per wall s since the run started) and the wall time left at that pace (ETA)."""
        if not self.progress:
            return
        k, every = self.plant.state.k, round(every_s * NS_PER_S / self.plant.dt_ns)
        if k // every != (k - self.steps_per_period) // every:
            t = self.plant.state.t
            o, s, mpa = self.out, self.summary, CV.MPA_TO_PA
            wall = time.monotonic() - self._wall0
            pace = f"  {t / wall:.1f}x real time, ETA {(self.scenario.duration_s - t) * wall / t:.0f} s" \
                if wall > 0 and t > 0 else ""
            self.progress(f"t={t:7.1f}/{self.scenario.duration_s:g} s  v={o.v:5.2f} m/s  T_CL={o.T_CL:6.1f}  "
                          f"T_CH={o.T_CH:6.1f} degC  P_CL={o.P_CL / mpa:4.2f}  P_CH={o.P_CH / mpa:4.2f} MPa  "
                          f"TCU {s.tcu_state}/{s.active_clutch}{pace}")

    @property
    def n_periods(self) -> int:
        return int(round(self.scenario.duration_s / self.period))

    # ---- lock-step ------------------------------------------------------------------------------------------
    def run_lockstep(self, reply_timeout: float = 5.0, pump: Callable[[], None] | None = None,
                     startup_timeout: float = 60.0) -> RunSummary:
        """Run the scenario in lock-step (:class:`~dsg_hil.protocol.lockstep.LockstepMaster`). ``pump`` lets an
        in-process TCU answer (python-can ``virtual``).

        First the presence handshake (not logged), for up to ``startup_timeout`` s (then :class:`PeerTimeout`);
        so the run starts from the same state whenever the TCU came up. Then each tick is re-sent while its
        answer is late; a TCU silent for ``reply_timeout`` wall-clock seconds (summed over ticks in a row given up, at
        least 3 of them) ends the run with :class:`PeerLost`
        (stop reason ``peer_lost``), the summary being valid up to that point. Compiled code is loaded before the
        handshake: once the TCU has answered, a pause of seconds (numba's cache loaded under emulation) would
        look to it like a plant gone."""
        self.summary.creep.prepare()
        link = self.link
        link.handshake(startup_timeout, pump)
        self._running = True
        self._keep = link.keep
        driver_at, state, steps = self.scenario.driver_at, self.plant.state, self.steps_per_period
        report = self.progress
        t0 = self._wall0 = time.monotonic()
        try:
            for tick in range(self.n_periods):
                t = tick * self.period  # the frames' stamp [s]; the schedule counts whole ms
                driver = driver_at(state.t)  # the driver's inputs this period (the plant's time, not t)
                link.start(tick)
                self._publish_period(tick, t, driver)  # the period's frames, its tick last
                if self.on_tick is not None:
                    self.on_tick()
                if pump is not None:
                    pump()
                link.answer(t, reply_timeout, pump)  # False: given up (the master warns once per episode)
                self._check_command(t)
                self._advance(steps, t, driver)
                if report:
                    self._report()
        except PeerLost:
            self.summary.stop_reason = "peer_lost"
            raise
        finally:
            self._keep = None
            self.summary.wall_time_s = time.monotonic() - t0
        return self.summary

    # ---- real time ------------------------------------------------------------------------------------------
    def run_realtime(self, clock: Callable[[], float] = time.monotonic) -> RunSummary:
        """Run the scenario paced by ``clock``: one plant step per ``dt`` against absolute deadlines.

        Command validity is judged on the clock (a dead TCU is dead in wall time); a machine too slow to keep
        up makes the run late, which is counted and reported as ``realtime_factor``."""
        start = clock()
        self._running, self._wall0 = True, time.monotonic()
        dt, dt_ns = self.plant.dt, self.plant.dt_ns
        n_steps = int(round(self.scenario.duration_s / dt))
        for k in range(n_steps):  # the step count is an integer; the clock's time a float (monotonic seconds)
            t = k * dt
            self._publish_due(k * dt_ns // NS_PER_MS, stamp=start + t)
            deadline = start + (k + 1) * dt
            while (msg := self.bus.recv(timeout=max(deadline - clock(), 0.0))) is not None:
                on_bus = msg.timestamp  # until this step's deadline: take what arrives
                status, frame = self._take(msg, clock() - start, stamp=start + t)
                if status == NEW and frame is not None and frame.name == self._cmd_name:
                    self._cmd_on_bus = on_bus
            now = clock() - start
            self._check_command(now)
            if self._cmd_on_bus is not None:  # the newest command is used from this step on
                latency = time.time() - self._cmd_on_bus
                if 0.0 <= latency < 1.0:  # bus timestamps are wall-clock (socketcan, virtual)
                    self.summary.command_latency_s.append(latency)
                self._cmd_on_bus = None
            self._advance(1, now)
            if (k + 1) % self.steps_per_period == 0:  # a period's last step, as in lock-step (t=10.0 of 10 s)
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
        without their answer, ``unanswered_episodes``: runs of them in a row; ``probes``: lock-step presence
        probes it took to find the TCU."""
        rx, retries, sent_by = self.rx.counts(), self.retries, self.sent_by
        by_message = {}
        for name in self.io.uses:
            got = rx.get(name, {"received": 0, "taken": 0, "rejected": {}, "lost": 0, "duplicates": 0})
            by_message[name] = {"sent": sent_by[name], "retries": retries[name], **got}
        return {"sent": self.sent, "received": self.rx.received, "rejected": self.rx.rejected_total,
                "retries": sum(retries.values()), "lost": sum(m["lost"] for m in rx.values()),
                "duplicates": sum(m["duplicates"] for m in rx.values()), "unanswered_ticks": self.unanswered_ticks,
                "unanswered_episodes": self.link.unanswered_episodes,
                "probes": self.probes, "by_message": by_message}
