"""The TCU process: owns its bus, decodes the plant's frames, runs the controller each command cycle.

Lock-step or real time is decided by the plant: once a SIM_SYNC tick has been seen, the TCU answers each tick
(controller time = tick x cycle time) and sends nothing on its own. It transmits nothing before it has heard the
plant, and free-runs on its monotonic clock at the TCU_CMD cycle time only when no tick has come within
``SYNC_WAIT_S`` of the plant's first frame (a real-time plant sends no ticks). A lock-step plant first probes for
the TCU (SIM_SYNC with the Tick the DBC names PROBE, 0xFFFFFFFF): the TCU resets itself and answers, and the run
starts from there. The lock-step answering is the protocol's TCU end,
:class:`dsg_hil.protocol.lockstep.LockstepResponder`; this module keeps inputs -> control.

Lost frames cost a retry, not the run: a plant that hears no answer re-sends the period's frames and its tick;
the TCU answers a repeated tick (or probe) with the very frames it already sent for it, byte for byte (same
counters), without stepping again. Repeats of frames it already has are duplicates: counted and ignored, not
errors. A tick whose plant frames are incomplete (the lock-step plant sends every message due at the tick's time,
each on its DBC cycle from t = 0) waits for them: it is answered when the last one comes (delivered after the tick,
as several CPUs may deliver, or re-sent with the period); only the third sight of the same tick is answered with
what the TCU has (counted as ``incomplete_answers``). A plant frame belongs to the tick its counter says; a tick
that does not follow the last answered one (ticks the TCU never saw) waits for the next to confirm it.

Before the controller sees the plant's values, VehicleSpeed is voted against the clutch-output speeds
(:mod:`ecu_stub.plausibility`): replaced by theirs when it alone is implausible, FAULT when no two agree; and the
thermal inputs (measured pressures, clutch input speed, oil leaving each clutch) are checked against the TCU's own
command, the engine speed and the sump / plate estimate (:mod:`ecu_stub.sensor_checks`): replaced by a
conservative value when implausible.

Listeners (``--log``) get every frame the TCU took (new, valid) and every frame it sent, first transmissions
only (neither the presence handshake nor re-sent answers), as the plant logs its side: in lock-step stamped with
the tick's time, so the same run gives the same record; else with the wall clock.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from typing import Any, cast

import can

from dsg_hil.common.units import CV
from dsg_hil.protocol import Codec, RxMonitor, TxScheduler
from dsg_hil.protocol.diag import diag_ids, load_description
from dsg_hil.protocol.frame import FrameListener, data_frame
from dsg_hil.protocol.lockstep import Frames, LockstepResponder, Received, frame_io
from dsg_hil.protocol.validity import RxState, all_valid

from .calibration import TcuCalibration
from .controller import CreepController, TcuInputs, TcuOutputs
from .diag import DiagServer
from .diag.server import response_frame
from .interface import SidePort, TcuController
from .plausibility import BRAKE_SETTLE_S, PeakHold, SpeedVoter, Verdict
from .sensor_checks import CHECKED, FALL_START_TAU, SensorChecks
from .tcu_io import CLUTCH_VALUES, SHIPPED, STATE_VALUES, TcuIO

__all__ = ["FAULT_IMPLAUSIBLE", "REQUIRED", "TCU_RX", "TCU_TX", "TCU_USES", "TX_VALUES", "TcuRunner"]

log = logging.getLogger(__name__)

TCU_RX = SHIPPED.rx  # the shipped matrix's (ecu_stub.tcu_io): by message read, its signals; the tick's last
TCU_TX = SHIPPED.tx  # by message sent, in the order of an answer (TCU_CMD last)
TCU_USES = SHIPPED.uses
TX_VALUES = SHIPPED.tx_values  # by message sent, each signal's value: an expression of the controller's outputs
# ``out`` (and the tick's ``echo``), ``states`` and ``clutches`` the DBC's value tables
REQUIRED = SHIPPED.required
FAULT_BITS = {"crc": 0x02, "counter": 0x04, "range": 0x08, "dlc": 0x08, "malformed": 0x08}
FAULT_IMPLAUSIBLE = 0x10  # TCU_STATUS.FaultBits bit 4: a valid frame's value failed a plausibility check
SYNC_WAIT_S = 1.0  # plant heard this long without a SIM_SYNC: it runs in real time
DRAIN_MAX = 256  # real time: frames already waiting taken before a control cycle, at most (a busy bus: go on)


class TcuRunner:
    """ecu-stub's TCU: the plant's frames -> :meth:`inputs` -> the controller -> :meth:`control` (TCU_STATUS,
    TCU_CMD). In lock-step its end of the protocol (``link``, a
    :class:`~dsg_hil.protocol.lockstep.LockstepResponder`, which also keeps the receive checks ``rx`` and the
    transmit schedule ``tx``) runs the control step per tick; in real time :meth:`run` does, on its own clock."""

    def __init__(self, codec: Codec, bus: can.BusABC, controller: TcuController | None = None,
                 listeners: Sequence[FrameListener] = (),
                 xcp: Callable[[Any, Callable[[int, bytes], None]], SidePort] | None = None,
                 io: TcuIO | None = None) -> None:
        self.io: TcuIO = io or SHIPPED  # the matrix's messages and signals (a binding's; ``codec`` uses them)
        io = self.io
        for name in io.uses:
            codec.message(name)
        self.codec, self.bus = codec, bus
        self.listeners = tuple(listeners)
        self._channel = getattr(bus, "channel", None)  # of the frames recorded for the listeners
        self._send_frame, recv = frame_io(bus, codec.fd)  # the in-process bus: frames as (ID, data), no can.Message
        # (a controller given is built on this matrix's steps: CreepController(cal, io.matrix_steps))
        self.controller: TcuController = controller or CreepController(None, io.matrix_steps)
        command = io.names[2]
        self.cycle = codec.cycle_time(command)
        self.cycle_ms = codec.cycle_time_ms(command)
        # the state's and active clutch's numbers on the matrix: the quantities' (the shipped DBC's VAL_ numbering:
        # dsg_hil.protocol.binding.QUANTITIES), or its own value table's where its binding names them (values)
        self.states, self.clutches = dict(io.state_values), dict(io.clutch_values)
        # the plant's values in the TCU's units (see inputs): (index of the message in REQUIRED, signal, k, c)
        self._inputs = io.inputs
        self._v_index = io.inputs[4][0]  # the message of VehicleSpeed (its counter: the speed vote)
        # the TCU's time of the frames it sends (fault windows): the tick's time (the float of its decimal, from whole
        # ms, as the plant's clock), or run time; < 0 before
        self.now = -1.0
        self.last: TcuOutputs | None = None
        self.sent = 0
        # (outputs, echo, counter) -> frame data, by message (the controller's outputs in the DBC's values and units)
        names = {"states": self.states, "clutches": self.clutches}
        self._frame_data = {name: codec.expression_encoder(name, ("out", "echo"), values, names)
                            for name, values in io.tx_values.items()}
        self._required_of: RxMonitor | None = None  # see inputs
        self._required: tuple[RxState, ...] = ()
        # VehicleSpeed voted against the clutch outputs' speeds (ecu_stub.plausibility) with the calibration's speed
        # ratios; none for a controller without a TcuCalibration (an FMU: it brings its own checks). Control cycles
        # whose VehicleSpeed the vote replaced ("VehicleSpeed") or whose speeds it found all implausible ("speeds")
        self.speed_vote: SpeedVoter | None = None
        self.sensor_checks: SensorChecks | None = None
        # the speed vote's step check: the last cycle whose outputs requested the full brake; the driver's pedal [%]
        # and the deceleration the outputs requested [m/s^2] over the last BRAKE_SETTLE_S; a full pedal's
        # deceleration and half the DBC step of DecelRequest [m/s^2]
        self._braked_at = -math.inf
        self._pedal_pct, self._decel_mps2 = PeakHold(BRAKE_SETTLE_S), PeakHold(BRAKE_SETTLE_S)
        self._brake_full_mps2, self._decel_q_mps2 = math.inf, 0.0
        cal = getattr(self.controller, "cal", None)
        if isinstance(cal, TcuCalibration):
            step, matrix = io.step, io.matrix_steps  # a signal's step in the TCU's unit, by quantity; the matrix's

            self._brake_full_mps2 = cal.vehicle.brake_decel_mps2
            self._decel_q_mps2 = 0.5 * step("decel_request")
            vehicle = io.message("v")
            self.speed_vote = SpeedVoter(cal.CL.speed_ratio_m, cal.CH.speed_ratio_m, step("v"),
                                         max(step("omega_CL"), step("omega_CH")), codec.cycle_time(vehicle),
                                         codec.protection(vehicle).counter_modulus or 16,  # (0: no counter)
                                         matrix.max_dt_s)
            self.sensor_checks = SensorChecks(
                cal.strategy.hydraulic_lag_s, 0.5 * (step("P_CL") + step("P_CL_cmd")),
                cal.vehicle.input_ratio,
                0.5 * (step("omega_in") + step("omega_e") / cal.vehicle.input_ratio),
                {c: k.cooling_w_k / (k.K_plate_oil_w_k + k.cooling_w_k) for c, k in (("CL", cal.CL), ("CH", cal.CH))},
                {c: k.K_plate_oil_w_k * k.cooling_w_k / (k.K_plate_oil_w_k + k.cooling_w_k) / k.C_plate_j_k
                 for c, k in (("CL", cal.CL), ("CH", cal.CH))},
                FALL_START_TAU * cal.strategy.startup_observer_s / 5.0, cal.strategy.startup_observer_s / 5.0,
                matrix.max_dt_s, matrix.oil_frame_s)
        # cycles whose thermal input a check replaced, by signal (ecu_stub.sensor_checks)
        self.implausible = {"VehicleSpeed": 0, "speeds": 0, "CLOutputSpeed": 0, "CHOutputSpeed": 0,
                            **dict.fromkeys(CHECKED, 0)}
        # UDS on the DBC's diagnostic IDs (ecu_stub.diag): requests taken before the lock-step end sees a frame
        self.diag: DiagServer | None = None
        if codec.db.dbc is not None and "DiagRequestId" in codec.db.dbc.attributes:
            request_id, response_id = diag_ids(codec.db)
            self.diag = DiagServer(load_description(), request_id, response_id, self._send_diag, dict(STATE_VALUES),
                                   dict(CLUTCH_VALUES), cal.strategy.T_safe_c if isinstance(cal, TcuCalibration)
                                   else math.nan, repr(cal), messages=io.renames(SHIPPED))
        # XCP on its own IDs (ecu_stub.xcp): ``xcp(runner, send)`` builds the slave; None: no XCP
        self.xcp: SidePort | None = xcp(self, self._send_diag) if xcp is not None else None
        self.link = LockstepResponder(codec, io.rx, io.tx, io.required, step=self._step, restart=self._restart,
                                      send=self._send_one, recv=self._diag_recv(recv),
                                      on_taken=self._taken if listeners else None, names=io.names)

    # the bus side, kept by the lock-step end
    @property
    def rx(self) -> RxMonitor:
        return self.link.rx

    @property
    def tx(self) -> TxScheduler:
        return self.link.tx

    @property
    def lockstep(self) -> bool:
        return self.link.lockstep

    @property
    def heard_plant_at(self) -> float | None:
        return self.link.heard_at

    @property
    def answers_resent(self) -> int:
        return self.link.answers_resent

    @property
    def incomplete_answers(self) -> int:
        return self.link.incomplete_answers

    def inputs(self, now: float) -> TcuInputs:
        rx = self.rx
        faults = 0
        if rx.rejected:
            for reason, n in rx.rejected.items():
                if n:
                    faults |= FAULT_BITS.get(reason, 0)
        if rx is not self._required_of:  # the states of REQUIRED, looked up once per receive monitor
            self._required_of, self._required = rx, tuple(rx.states[name] for name in self.io.required)
        required = self._required
        if not all_valid(required, now):
            return TcuInputs(plant_valid=False, fault_bits=faults)
        # the plant's values in the TCU's units (ecu_stub.tcu_io.INPUTS' order): as they are where k is 1
        values = [state.values for state in required]
        (engine, clutch_in, cl_out, ch_out, v_mps, accel, P_CL, P_CH, T_CL, T_CH, T_sump, creep, pedal,
         desired) = [values[i][signal] if k == 1.0 and c == 0.0 else values[i][signal] * k + c
                     for i, signal, k, c in self._inputs]
        vote = self.speed_vote
        verdict = Verdict.OK
        if vote is not None:
            verdict, v_mps = vote.update(v_mps, cl_out, ch_out, now, required[self._v_index].last_counter,
                                         self._brake_mps2(pedal, now))
        if verdict is not Verdict.OK:  # a sensor fault: VehicleSpeed replaced by the shafts' speed, or none trusted
            faults |= FAULT_IMPLAUSIBLE
            if verdict is Verdict.FAULT:
                self.implausible["speeds"] += 1
                return TcuInputs(plant_valid=False, fault_bits=faults)  # FAULT: clutches open, brake requested
            self.implausible["VehicleSpeed"] += 1
        if vote is not None and vote.outvoted:  # an output speed out-voted: the vehicle's, through its ratio (the slip)
            faults |= FAULT_IMPLAUSIBLE
            if vote.outvoted == "CL":
                cl_out, self.implausible["CLOutputSpeed"] = v_mps / vote.speed_ratio_cl_m / CV.RPM_TO_RAD_S, \
                    self.implausible["CLOutputSpeed"] + 1
            else:
                ch_out, self.implausible["CHOutputSpeed"] = v_mps / vote.speed_ratio_ch_m / CV.RPM_TO_RAD_S, \
                    self.implausible["CHOutputSpeed"] + 1
        trusted, ratio_CL, ratio_CH = True, 0.0, 0.0
        if (checks := self.sensor_checks) is not None:
            P_CL, P_CH, clutch_in, T_CL, T_CH, failing = checks.check(
                P_CL, P_CH, clutch_in, engine, T_CL, T_CH, T_sump,
                getattr(self.controller, "T_pred", None), now)
            if failing:  # a sensor fault: the value replaced by a conservative one
                faults |= FAULT_IMPLAUSIBLE
                for name in failing:
                    self.implausible[name] += 1
                trusted = "P_CL" not in failing and "P_CH" not in failing
            ratio_CL, ratio_CH = checks.oil["CL"].undetected_ratio, checks.oil["CH"].undetected_ratio
        return TcuInputs(True, engine, clutch_in, cl_out, ch_out, v_mps, P_CL, P_CH, T_CL, T_CH, T_sump, creep >= 0.5,
                         pedal, desired, faults, trusted, accel, ratio_CL, ratio_CH)

    def _brake_mps2(self, pedal_pct: float, now: float) -> float:
        """The most deceleration a brake may add now [m/s^2] (the speed vote's step check,
        :mod:`ecu_stub.plausibility`): any while the TCU's full-brake request may act (:data:`BRAKE_SETTLE_S` after
        it), else the larger of the driver's pedal times the calibration's full-pedal deceleration and the
        deceleration the TCU requested (+ half its DBC step), each the largest over the last
        :data:`BRAKE_SETTLE_S`."""
        self._pedal_pct.add(now, pedal_pct)
        if now - self._braked_at <= BRAKE_SETTLE_S:
            return math.inf
        pedal = self._pedal_pct.peak(now) / 100.0 * self._brake_full_mps2
        decel = self._decel_mps2.peak(now)
        return max(pedal, decel + self._decel_q_mps2) if decel > 0.0 else pedal

    def control(self, now: float, echo: int = 0) -> Frames:
        """One controller cycle at ``now``, its frames sent (see :meth:`_step`); returns them, as (ID, data)."""
        frames = self._step(now, echo)
        self._send(frames)
        return frames

    def _step(self, now: float, echo: int) -> Frames:
        """One controller cycle at ``now``: compute, then TCU_STATUS when due and TCU_CMD, last (in lock-step it
        completes the answer to the tick), recorded for the listeners; returns the frames, unsent."""
        link = self.link
        lockstep, tick_ms = link.lockstep, link.tick * self.cycle_ms
        self.now = tick_ms / CV.S_TO_MS if lockstep else now
        inp = self.inputs(now)
        out = self.controller.update(inp, now)
        self.last = out
        if self.diag is not None:
            self.diag.period(self.now, now, self.rx, self.implausible, inp, out,
                             getattr(self.controller, "held_untrusted", False) is True)
        if self.xcp is not None:
            self.xcp.period(self.now)
        if out.brake_request:  # (the speed vote's step check: any deceleration, _brake_mps2)
            self._braked_at = now
        self._decel_mps2.add(now, out.decel_request_mps2)
        if self.sensor_checks is not None:
            self.sensor_checks.commanded(out.P_CL_cmd_mpa, out.P_CH_cmd_mpa)
        tx, frames = link.tx, []
        due = tx.due_ms(tick_ms) if lockstep else tx.due(now)  # lock-step: whole ms
        for name in self._frame_data:  # TCU_STATUS, then TCU_CMD (the command last)
            if name in due:
                frames.append((tx.ids[name], self._frame_data[name](out, echo, tx.next_counter(name))))
        if self.listeners:
            for frame_id, data in frames:
                self._record(frame_id, data, now, is_rx=False)
        return frames

    def _restart(self, now: float) -> None:
        """A lock-step run starts (the presence probe, or a first tick): a fresh controller, the plant's time."""
        fresh = cast(Callable[[Any], TcuController], type(self.controller))  # its class, built from its cal
        self.controller = fresh(self.controller.cal)
        if self.speed_vote is not None:
            self.speed_vote.reset()
        self._braked_at = -math.inf
        self._pedal_pct.clear()
        self._decel_mps2.clear()
        if self.sensor_checks is not None:
            self.sensor_checks.reset()
        self.now = now
        if self.diag is not None:
            self.diag.new_operation_cycle()

    def _taken(self, frame_id: int, data: bytes, stamp: float) -> None:
        self._record(frame_id, data, stamp, is_rx=True)

    def _record(self, frame_id: int, data: bytes, stamp: float, is_rx: bool) -> None:
        """Hand a frame taken or sent to the listeners, stamped ``stamp`` (lock-step), else with the wall clock."""
        msg = data_frame(frame_id, data, stamp if self.lockstep else time.time(), self._channel, is_rx,
                         fd=self.codec.fd)
        for listener in self.listeners:
            listener(msg)

    def _send(self, frames: Frames) -> None:
        for frame_id, data in frames:
            self._send_one(frame_id, data)

    def _send_one(self, frame_id: int, data: bytes) -> None:
        self._send_frame(frame_id, data)
        self.sent += 1

    def handle(self, msg: can.Message, now: float) -> bool:
        """Take one frame (:meth:`LockstepResponder.handle`): a SIM_SYNC tick is answered at once. True if the
        frame was the plant's (even a duplicate or a rejected one: the plant is alive). A diagnostic request goes to
        :attr:`diag`."""
        if self._is_diag(msg):
            return False
        return self.link.handle(msg, now)

    def handle_data(self, frame_id: int, data: bytes, now: float) -> bool:
        """:meth:`handle` of a classic data frame with an 11-bit ID, given by its ID and data."""
        if self._to_side(frame_id, data):
            return False
        return self.link.handle_data(frame_id, data, now)

    def _to_side(self, frame_id: int, data: bytes | bytearray) -> bool:
        """Hand a frame on the diagnostic request ID to :attr:`diag`, one on the XCP command ID to :attr:`xcp`; True
        if one took it (its data copied only then: every received frame passes here)."""
        diag, xcp = self.diag, self.xcp
        if diag is not None and frame_id == diag.request_id:
            diag.take(bytes(data))
            return True
        if xcp is not None and frame_id == xcp.request_id:
            xcp.take(bytes(data))
            return True
        return False

    def _is_diag(self, item: object) -> bool:
        """Whether ``item`` (a can.Message, or (ID, data) from the in-process bus) is a diagnostic request or an XCP
        command; it is handed to :attr:`diag` or :attr:`xcp` then."""
        if isinstance(item, can.Message):
            if item.is_extended_id or item.is_remote_frame or item.is_error_frame:
                return False
            return self._to_side(item.arbitration_id, item.data)
        if isinstance(item, tuple):
            return self._to_side(item[0], item[1])
        return False

    def _diag_recv(self, recv: Callable[[float], Received | None]) -> Callable[[float], Received | None]:
        """``recv`` that hands diagnostic requests to :attr:`diag` and gives the other frames."""
        def take(timeout: float) -> Received | None:
            while True:
                item = recv(timeout)
                if item is None or not self._is_diag(item):
                    return item
        return take if self.diag is not None or self.xcp is not None else recv

    def _send_diag(self, frame_id: int, data: bytes) -> None:
        """A diagnostic or XCP response frame: classic, or CAN FD beyond 8 bytes (not counted in :attr:`sent`)."""
        if len(data) <= 8:
            self._send_frame(frame_id, data)
        else:
            self.bus.send(response_frame(frame_id, data))

    def frame_counts(self) -> dict:
        """What the TCU heard and sent: totals and, per message it reads, received, rejected by cause, lost
        (counter gaps) and duplicates; lock-step ticks the plant went on from without the TCU (``ticks_missed``,
        see :class:`LockstepResponder`); and the control cycles with implausible speeds, by cause
        (``implausible``: VehicleSpeed replaced by the shafts' speed, or no speed trusted; and by signal the cycles
        whose P_CL, P_CH, ClutchInputSpeed, T_OilCL or T_OilCH a check of :mod:`ecu_stub.sensor_checks` replaced)."""
        rx = self.rx.counts()
        return {"sent": self.sent, "answers_resent": self.answers_resent, "implausible": dict(self.implausible),
                "incomplete_answers": self.incomplete_answers, "ticks_missed": self.link.ticks_missed,
                "received": self.rx.received,
                "rejected": self.rx.rejected_total, "lost": sum(m["lost"] for m in rx.values()),
                "duplicates": sum(m["duplicates"] for m in rx.values()), "by_message": rx}

    def free_running(self, now: float) -> bool:
        """True once the plant has been heard for a while without a tick: a real-time plant."""
        return (not self.lockstep and self.heard_plant_at is not None
                and now - self.heard_plant_at > SYNC_WAIT_S)

    def pump(self) -> None:
        """Handle every frame already waiting (for an in-process peer on python-can's virtual bus)."""
        self.link.pump()

    def run(self, duration: float | None = None, clock: Callable[[], float] = time.monotonic,
            idle_timeout: float | None = None, should_stop: Callable[[], bool] = lambda: False) -> None:
        """Serve the bus until ``duration`` [s] has passed (None: forever), ``should_stop()`` is true, or the plant
        has been silent for ``idle_timeout`` seconds after having been heard."""
        start = clock()
        origin, cycles = start, 0  # free-running: control cycle n is due at origin + n cycle times (n an integer)
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
                origin, cycles, next_cycle = now, 0, now
            elif now >= next_cycle:
                for _ in range(DRAIN_MAX):  # what waits first: a starved TCU controls on the newest frames
                    if (queued := self.bus.recv(timeout=0.0)) is None:
                        break
                    if self.handle(queued, (now := clock()) - start):
                        last_heard = now
                self.control(now - start)
                cycles += 1
                if origin + cycles * self.cycle <= now:  # fell behind: skip, keep the grid
                    cycles = int((now - origin) // self.cycle) + 1
                    if origin + cycles * self.cycle <= now:  # the division rounded a cycle down: strictly later
                        cycles += 1
                next_cycle = origin + cycles * self.cycle
