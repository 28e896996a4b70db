"""The lockstep protocol (docs/reference/contract.md, *Lockstep, step by step*), both ends:
:class:`LockstepMaster`, the plant's (the time master), and :class:`LockstepResponder`, the TCU's.

Neither owns a bus: each is given ``send`` and ``recv`` callables (classic data frames as (ID, data), or
python-can messages; see :func:`frame_io`), the master also its clock (``time.monotonic``). What a node sends in a
period and what its control step is stay the node's, passed in as callbacks. The messages and signals are the
DBC's: SIM_SYNC.Tick (the presence probe is its value named ``PROBE``), TCU_CMD.SyncEcho, TCU_STATUS.

Both ends count ticks (integers: which period a frame came in, which tick brought the last TCU_STATUS, a cycle
in whole ticks from the DBC's milliseconds); seconds (tick x cycle time) are derived where frames are stamped.
"""

from __future__ import annotations

import logging
import math
import time
from collections import Counter as Tally
from collections.abc import Callable, Iterable
from typing import TypeAlias

import can

from ..common.errors import PeerLost, PeerTimeout  # the lock-step's errors, in the one tree
from .codec import Codec, DecodedFrame, ProtocolError
from .faults.spec import FaultSpec
from .frame import data_frame
from .validity import DUPLICATE, IGNORED, NEW, REJECTED, TIMEOUT_CYCLES, RxMonitor, RxState, TxScheduler

__all__ = ["LOST_AFTER_TICKS", "PROBE", "PROBE_INTERVAL_S", "RETRIES_IN_EPISODE", "RETRIES_PER_TICK",
           "RETRY_FIRST_S", "RETRY_MAX_S", "SIGHTS_BEFORE_INCOMPLETE", "STATUS_RETRIES", "WAITING_NOTICE_S", "Frames",
           "LockstepMaster", "LockstepResponder", "PeerLost", "PeerTimeout", "Received", "answers_lost_by", "choices",
           "frame_io", "probe_tick"]

log = logging.getLogger(__name__)

SYNC, TICK, CMD, ECHO, STATUS = "SIM_SYNC", "Tick", "TCU_CMD", "SyncEcho", "TCU_STATUS"
PROBE = "PROBE"  # the DBC's name of the SIM_SYNC Tick value of the presence probe (VAL_)
PROBE_INTERVAL_S = 0.2  # master: wall-clock wait for the probe's answer before probing again [s]
RETRY_FIRST_S = 0.1  # master: wall-clock wait for a tick's answer before the first re-send [s]
RETRY_MAX_S = 1.0  # ... the wait doubles after each re-send up to this [s]
RETRIES_PER_TICK = 6  # ... re-sends before the tick is given up (0.1+0.2+0.4+0.8+1+1+1 = 4.5 s in all)
RETRIES_IN_EPISODE = 1  # ... for the next ticks while none is answered, or a known fault may lose it (0.3 s)
LOST_AFTER_TICKS = int(TIMEOUT_CYCLES)  # ... a silent TCU is lost only with this many ticks in a row unanswered
WAITING_NOTICE_S = 10.0  # master: while the handshake waits, say so at its start and then this often [s]
STATUS_RETRIES = 2  # ... re-sends for a TCU_STATUS missing from an answer, before going on without it
SIGHTS_BEFORE_INCOMPLETE = 3  # responder: a tick seen this often is answered even with plant frames missing

Frames = list[tuple[int, bytes]]  # (ID, data) of data frames, each in its message's format (classic or CAN FD)
# what ``recv`` gives: a classic data frame as (ID, data), or any message (an explicit alias: setup.py's mypyc build
# types python-can as Any, where an implicit one would be a variable)
Received: TypeAlias = tuple[int, bytes] | can.Message


def choices(codec: Codec, message: str, signal: str) -> dict[str, int]:
    """The DBC's value table (VAL_) of ``message.signal``: {name: value}."""
    table = codec.message(message).get_signal_by_name(signal).choices
    return {str(name): int(value) for value, name in (table or {}).items()}


def probe_tick(codec: Codec, sync: str = SYNC, tick: str = TICK) -> int:
    """The SIM_SYNC Tick (``sync``.``tick``) of the presence probe: the DBC's value named ``PROBE``."""
    try:
        return choices(codec, sync, tick)[PROBE]
    except KeyError:
        raise ProtocolError(f"DBC {sync}.{tick} lacks the VAL_ entry {PROBE!r} (the lock-step presence probe)") \
            from None


def answers_lost_by(faults: Iterable[FaultSpec]) -> Callable[[float], bool]:
    """For :meth:`LockstepMaster.excuse`: whether one of the TCU's ``faults`` (windows on its clock, the tick's time
    in lock-step) may lose the answer to the tick at ``t``: any but ``duplicate`` on TCU_CMD or TCU_STATUS."""
    windows = [spec for spec in faults if spec.message in (CMD, STATUS) and spec.kind != "duplicate"]
    return lambda t: any(spec.active(t) for spec in windows)


def frame_io(bus: can.BusABC, fd: dict[int, bool] | None = None
             ) -> tuple[Callable[[int, bytes], None], Callable[[float], Received | None]]:
    """``send(frame_id, data)`` and ``recv(timeout)`` of data frames on ``bus``: the direct (ID, data) path of the
    in-process bus (:class:`~dsg_hil.protocol.local.LocalBus`, unwrapped), else python-can messages, CAN FD ones for
    the IDs in ``fd`` (a codec's :attr:`~.codec.Codec.fd`)."""
    send_data = getattr(bus, "send_data", None)
    recv_data = getattr(bus, "recv_data", None)

    def send(frame_id: int, data: bytes) -> None:
        bus.send(data_frame(frame_id, data, fd=fd))
    return send_data or send, recv_data or bus.recv


class LockstepMaster:
    """The plant's end: the presence handshake (:meth:`handshake`), then per tick (:meth:`start`, the node's
    frames, the SIM_SYNC tick of :meth:`tick_data`) the wait for the answer with re-sends (:meth:`answer`).

    ``receives``: the TCU's messages the master checks (``rx``, renewed by the handshake; real time uses it alone).
    ``send(frame_id, data, stamp)`` puts a frame on the bus (``stamp``: the simulated time of the period, 0 for a
    probe); ``recv(timeout)`` gives the next frame or None after ``timeout`` seconds (both attributes, re-bound
    when the node's bus changes); ``use(frame, received, t)`` gets each new frame of the TCU's that passed its
    checks, once the tick's answer is complete, TCU_CMD last (as the TCU sends them, whatever re-sends brought
    them); ``clock`` times the waits. The node sends its period's frames itself (the tick too) and hands each to
    :meth:`keep`, for re-sending."""

    def __init__(self, codec: Codec, receives: Iterable[str], send: Callable[[int, bytes, float], object],
                 recv: Callable[[float], Received | None], use: Callable[[DecodedFrame, Received, float], None],
                 clock: Callable[[], float] = time.monotonic,
                 names: tuple[str, str, str, str, str] = (SYNC, TICK, CMD, ECHO, STATUS)) -> None:
        self.codec = codec
        self._sync_name, self._tick_name, self._cmd_name, self._echo_name, self._status_name = names
        self._receives = list(receives)
        self.send, self.recv = send, recv  # re-bound by the node when its bus changes
        self._use, self._clock = use, clock
        self.rx = RxMonitor(codec, self._receives)
        sync_name, cmd_name = self._sync_name, self._cmd_name
        self.sync = TxScheduler(codec, [sync_name])
        self._tick_encoder = codec.expression_encoder(sync_name, ("tick",), {self._tick_name: "tick"})  # (tick, ctr)
        self.probe = probe_tick(codec, sync_name, self._tick_name)
        self.sync_id, self._cmd_id = codec.frame_id(sync_name), codec.frame_id(cmd_name)
        self.period = codec.cycle_time(cmd_name)
        # in control periods:
        self._status_every = round(codec.cycle_time_ms(self._status_name) / codec.cycle_time_ms(cmd_name))
        self.retry_first_s, self.retry_max_s, self.retries_per_tick = RETRY_FIRST_S, RETRY_MAX_S, RETRIES_PER_TICK
        self.tick = 0
        self.probes = 0  # presence probes sent before tick 0 (not logged)
        self.unanswered_ticks = 0
        self.unanswered_episodes = 0  # runs of ticks in a row given up (one warning each)
        self.retries: Tally[int] = Tally()  # re-sends (not logged), by frame ID
        self.excused: Callable[[float], bool] = lambda t: False  # see :meth:`excuse`
        self.notify: Callable[[str], object] | None = None  # see :meth:`handshake`
        self._given_up = 0  # ticks given up in a row just before this one (their answers may come late)
        self._status_tick: int | None = None  # the tick whose answer brought the last TCU_STATUS
        self._silent_s = 0.0  # wall time waited in vain on ticks given up since the TCU was last heard
        self._frames: list[tuple[Frames, float]] = []  # this period's frames (batches, stamped), for re-sending

    # ---- the presence handshake -------------------------------------------------------------------------------
    def handshake(self, timeout: float, pump: Callable[[], None] | None = None) -> None:
        """Probe (SIM_SYNC with the probe's Tick, not logged) every ``PROBE_INTERVAL_S`` until the TCU answers
        (TCU_CMD with SyncEcho 255), which resets it; then start from clean counts, the receive counters following
        the answer (a repeat of it is a duplicate), SIM_SYNC's counter from 0. :class:`PeerTimeout` after
        ``timeout`` seconds. ``pump`` lets an in-process TCU answer. While no answer comes, ``notify`` (if set) is
        told so after the first probe, then every ``WAITING_NOTICE_S``."""
        clock = self._clock
        started = clock()
        deadline, notice_at = started + timeout, started + PROBE_INTERVAL_S
        while (now := clock()) < deadline:
            if self.notify is not None and now >= notice_at and self.probes:
                self.notify(f"lock-step: waiting for a TCU to answer ({now - started:.0f} of {timeout:g} s): start "
                            f"ecu-stub (or your TCU) on the same bus")
                notice_at = now + WAITING_NOTICE_S
            self.send(self.sync_id, self.sync.data(self._sync_name, {self._tick_name: self.probe}), 0.0)
            self.probes += 1
            if pump is not None:
                pump()
            probe_end = min(deadline, clock() + PROBE_INTERVAL_S)
            while (remaining := probe_end - clock()) > 0:
                item = self.recv(remaining)
                if item is None:
                    continue
                msg = data_frame(item[0], item[1], fd=self.codec.fd) if isinstance(item, tuple) else item
                frame = self.rx.receive(msg, 0.0)
                if frame is not None and frame.name == self._cmd_name \
                        and int(frame.values[self._echo_name]) == self.probe & 0xFF:
                    self.rx = RxMonitor(self.codec, self._receives)
                    self.rx.prime(msg)
                    self.rx.require(self._cmd_name, "echo", self._answers_tick)
                    self.sync = TxScheduler(self.codec, [self._sync_name])
                    self._status_tick = None
                    return
        raise PeerTimeout(f"no TCU answered the lock-step presence probe within {timeout:g} s: is the TCU "
                          f"(ecu-stub) running on the same bus?")

    # ---- ticks ---------------------------------------------------------------------------------------------------
    def start(self, tick: int) -> None:
        """Begin the period of ``tick``: the node's frames follow (:meth:`keep`), then the tick."""
        self.tick = tick
        self._frames.clear()

    def keep(self, frame_id: int, data: bytes, stamp: float) -> None:
        """A frame the node sent in this period (first transmission), re-sent with the period."""
        self._frames.append(([(frame_id, data)], stamp))

    def keep_all(self, frames: Frames, stamp: float) -> None:
        """:meth:`keep` of each of ``frames`` (not copied: the node leaves the list alone), in one call."""
        self._frames.append((frames, stamp))

    def tick_data(self) -> bytes:
        """The data of this period's SIM_SYNC tick (counter advanced); the node sends it last, ID ``sync_id``."""
        return self._tick_encoder(self.tick, self.sync.next_counter(self._sync_name))  # sync.data of {Tick: tick}

    def excuse(self, excused: Callable[[float], bool]) -> None:
        """Ticks whose answer a known, injected fault may lose (``excused(t)`` of the period time ``t``, the TCU's
        fault clock in lock-step): waited for as in an episode (``RETRIES_IN_EPISODE``), their silence never
        counted toward :class:`PeerLost`."""
        self.excused = excused

    def answer(self, t: float, reply_timeout: float, pump: Callable[[], None] | None = None) -> bool:
        """Wait for the TCU's answer to this tick (period time ``t``); True when the command came, False when the
        tick was given up (counted in ``unanswered_ticks``; a run of them in ``unanswered_episodes``, with one
        warning at its first tick and a note when the TCU answers again).

        The answer is the TCU_CMD whose SyncEcho is the tick's low byte (see ``_answers_tick`` for the others),
        after the TCU_STATUS when one is expected (see ``_status_expected``). While it is late the period's frames
        (tick included) are re-sent, byte for byte and not logged, after ``retry_first_s`` and then at doubling
        intervals up to ``retry_max_s``; at once when a TCU_CMD is rejected or comes without its TCU_STATUS (then
        ``STATUS_RETRIES`` times at most). The tick is given up after ``retries_per_tick`` re-sends, or after
        ``RETRIES_IN_EPISODE`` when the tick before was given up too or a known fault may lose its answer
        (:meth:`excuse`) and re-sends wait on the clock: an answer lost for good costs one long wait (a stalled
        TCU), not one per tick.

        The TCU's silence (nothing at all heard: the node's own time between waits does not count, nor does a stall
        of it, what arrived meanwhile is read first; nor do ticks excused) adds up over ticks given up in a row.
        Once it reaches ``reply_timeout`` seconds a tick is given up after its first wait, and on the
        ``LOST_AFTER_TICKS``-th tick in a row (the DBC's command timeout, 3 cycle times) the TCU is lost:
        :class:`PeerLost`. So a TCU that answers each tick once, never repeating an answer, rides out two lost
        answers in a row whatever the timeout."""
        excused = self.excused(t)
        answered = self._await(t, reply_timeout, pump, excused)
        if answered and self._given_up:
            log.info("t=%.2f s: the TCU answers again (tick %d) after %d tick(s) unanswered", t, self.tick,
                     self._given_up)
        elif not answered and not self._given_up:
            self.unanswered_episodes += 1
            log.warning("t=%.2f s: lock-step tick %d unanswered after its re-sends%s: the period runs on the last "
                        "command while it is valid (DBC: 3 cycle times), then unpowered; the next ticks unanswered "
                        "are counted, not logged", t, self.tick, " (an injected fault)" if excused else "")
        self._given_up = 0 if answered else self._given_up + 1
        self.unanswered_ticks += not answered
        return answered

    def _await(self, t: float, reply_timeout: float, pump: Callable[[], None] | None, excused: bool) -> bool:
        """:meth:`answer`'s wait. What already waits is read first, with no clock read: in-process the whole answer
        is there; the schedule of the waits and re-sends is set up only when the queue runs dry (``waiting``)."""
        clock, recv, rx, cmd_id = self._clock, self.recv, self.rx, self._cmd_id
        cmd_name, echo_name, status_name = self._cmd_name, self._echo_name, self._status_name
        waiting = retry_now = have_cmd = False  # retry_now: re-send at once when the queue runs dry
        since = first_wait = next_retry = silent_at = 0.0
        retries = status_retries = max_retries = 0
        interval, lost_tick = self.retry_first_s, False
        taken: list[tuple[DecodedFrame, Received]] = []
        try:
            while True:
                item = recv(0.0)
                if item is None:
                    if not waiting:
                        waiting = True
                        # (re-sends at once, in-process, cost no wall time: the whole schedule then, as the answers
                        # may need it)
                        short = (excused or self._given_up > 0) and self.retry_first_s > 0
                        max_retries = min(self.retries_per_tick, RETRIES_IN_EPISODE) if short \
                            else self.retries_per_tick
                        lost_tick = not excused and self._given_up + 1 >= LOST_AFTER_TICKS  # may end the run here
                        since = clock()  # silence is counted from here, plus ``_silent_s`` of ticks given up
                        first_wait = since + interval
                        next_retry = since if retry_now else first_wait
                    silent_at = math.inf if excused else max(first_wait, since + reply_timeout - self._silent_s)
                    item = recv(max(0.0, min(next_retry, silent_at) - clock()))
                if item is not None:
                    if isinstance(item, tuple):
                        frame_id = item[0]
                        status, frame = rx.take_data(frame_id, item[1], t)
                    else:
                        frame_id = item.arbitration_id
                        status, frame = rx.take(item, t)
                    if status != IGNORED:
                        self._silent_s = 0.0
                        if waiting:
                            since = clock()
                    if status == REJECTED and frame_id == cmd_id and not have_cmd:
                        retry_now, next_retry = True, clock() if waiting else 0.0  # failed its checks: ask again
                    elif status == NEW and frame is not None:
                        taken.append((frame, item))
                        if frame.name == cmd_name and int(frame.values[echo_name]) == self.tick & 0xFF:
                            have_cmd = True
                            if not self._status_expected():
                                return True
                            retry_now, next_retry = True, clock() if waiting else 0.0  # its TCU_STATUS was lost
                        elif frame.name == status_name:
                            self._status_tick = self.tick
                            if have_cmd:
                                return True
                    continue
                now = clock()
                if now >= silent_at:
                    if lost_tick:
                        raise PeerLost(f"TCU silent for {reply_timeout:g} s at lock-step tick {self.tick} (t={t:.2f} "
                                       f"s), {self._given_up + 1} ticks in a row unanswered: peer lost; the run ends "
                                       f"here")
                    self._silent_s += now - since
                    return have_cmd
                if now >= next_retry:
                    if have_cmd and status_retries == STATUS_RETRIES:
                        log.info("t=%.2f s: TCU_STATUS missing from the answer to tick %d", t, self.tick)
                        return True
                    if retries == max_retries:
                        if not excused:
                            self._silent_s += now - since
                        return have_cmd
                    self._resend()
                    retries += 1
                    status_retries += have_cmd
                    interval = min(2.0 * interval, self.retry_max_s)
                    next_retry = now + interval
                    if pump is not None:
                        pump()
        finally:
            if len(taken) > 1:
                taken.sort(key=lambda taken_frame: taken_frame[0].name == cmd_name)
            for frame, item in taken:
                self._use(frame, item, t)

    def _answers_tick(self, frame: DecodedFrame) -> str | None:
        """A TCU_CMD is taken only as the answer to the present tick (its SyncEcho the tick's low byte) or, late,
        to one of the ticks given up just before it (at most as many as a command stays valid, 3 cycle times);
        another (an old answer, a random frame that passed CRC and counter) is rejected ("echo")."""
        echo = int(frame.values[self._echo_name])
        late = (self.tick - echo) % 256
        if late == 0 or late <= min(self._given_up, int(TIMEOUT_CYCLES)):
            return None
        return f"SyncEcho {echo} answers no tick waiting (tick {self.tick})"

    def _status_expected(self) -> bool:
        """Whether this tick's answer should hold a TCU_STATUS: due now on its DBC cycle from tick 0, as the last
        one due came (so a TCU sending it on a schedule of its own costs no retries after tick 0)."""
        tick, every = self.tick, self._status_every
        if tick % every or self._status_tick == tick:
            return False
        return tick == 0 or self._status_tick == tick - every

    def _resend(self) -> None:
        send = self.send
        for frames, stamp in self._frames:
            for frame_id, data in frames:
                send(frame_id, data, stamp)
                self.retries[frame_id] += 1


class LockstepResponder:
    """The TCU's end: takes the plant's frames (receive checks in ``rx``; ``tx`` numbers the TCU's frames), answers
    each SIM_SYNC tick once with one control step, a repeated tick with the very frames it sent for it (no new
    step), and the presence probe by restarting.

    ``receives``, ``sends``: the messages the TCU reads (SIM_SYNC among them) and sends; ``required``: the plant
    messages a tick waits for (each due at its DBC cycle from tick 0). Callbacks: ``step(now, echo)`` runs one
    control step at ``now`` and returns the answer's frames (TCU_STATUS when due, TCU_CMD with SyncEcho ``echo``
    last), unsent; ``restart(now)``: a run starts (a fresh controller) whose next step comes after ``now``;
    ``send(frame_id, data)``, ``recv(timeout)`` as :func:`frame_io` gives them; ``on_taken(frame_id, data,
    stamp)``: each new plant frame but the probe (for a log). ``names``: the tick's message and signal, the
    command's message and its echo signal, the status message (a binding's; default the shipped DBC's).

    Lock-step is decided by the plant: ``lockstep`` is set by the first tick or probe. In lock-step, time is the
    plant's: frames arriving before a tick belong to it (their time the previous tick's + one cycle), so validity
    and controller time never depend on the wall clock. A plant frame completes the tick its counter says (the
    plant's counters restart at tick 0, one frame per cycle), however late or early it came. The TCU may miss
    ticks the plant goes on from (every copy lost: a flood overruns its receive queue): a tick that is not the
    one after the last answered (nor after the one waiting) is held until the next tick confirms it, so the TCU
    goes on at the plant's tick (``ticks_missed`` counts what it skipped) and a random frame that passed CRC and
    counter cannot set its time ahead of the plant's, where every real tick would look old."""

    def __init__(self, codec: Codec, receives: Iterable[str], sends: Iterable[str], required: Iterable[str], *,
                 step: Callable[[float, int], Frames], restart: Callable[[float], None],
                 send: Callable[[int, bytes], object], recv: Callable[[float], Received | None],
                 on_taken: Callable[[int, bytes, float], None] | None = None,
                 names: tuple[str, str, str, str, str] = (SYNC, TICK, CMD, ECHO, STATUS)) -> None:
        self.codec = codec
        self._sync_name, self._tick_name, self._cmd_name, self._echo_name, _ = names
        self._receives, self._sends = list(receives), list(sends)
        self._step, self._restart, self._send, self._recv, self._on_taken = step, restart, send, recv, on_taken
        self.rx = RxMonitor(codec, self._receives)
        self.tx = TxScheduler(codec, self._sends)
        self.probe = probe_tick(codec, self._sync_name, self._tick_name)
        self.cycle = codec.cycle_time(self._cmd_name)
        self.lockstep = False
        self.tick = 0  # the last tick answered (-1 after the probe: the next is tick 0)
        self.heard_at: float | None = None  # when the plant was first heard
        self.answers_resent = 0
        self.incomplete_answers = 0
        self._answered: int | None = None  # the tick last answered (the probe's Tick: the probe) ...
        self._answer: Frames = []  # ... the frames sent for it, re-sent if repeated ...
        self._answer_sends = 0  # ... and how often they were sent
        self._pending: int | None = None  # a tick not answered for want of plant frames ...
        self._pending_sights = 0  # ... and how often it was seen
        self._incomplete_run = 0  # ticks answered on the last values since an outage began (logged once) ...
        self._outage: set[str] = set()  # ... and the plant messages missing in it (until one of them is back)
        self._answered_early = False  # the tick answered came before its last plant frame (see handle_data)
        self._due_every: dict[str, int] = {}  # by plant message: due at every n-th tick (a whole n only)
        for name in required:
            every, rest = divmod(codec.cycle_time_ms(name), codec.cycle_time_ms(self._cmd_name))
            if not rest:
                self._due_every[name] = every
        self._taken_in: dict[str, int] = {}  # by plant message: its last new frame came after tick n - 1's answer
        self._due_of: RxMonitor | None = None  # _missing: the receive monitor whose states ``_due`` holds
        self._due: list[tuple[str, int, RxState]] = []
        self._unconfirmed: int | None = None  # a tick that did not follow the last one answered, held (see handle)
        self.ticks_missed = 0  # ticks the TCU never saw (it went on from a later tick of the plant's)

    @property
    def tick_time(self) -> float:
        """The time of the last tick answered [s]: its frames' time, the next tick's frames one cycle later."""
        return self.tick * self.cycle

    def pump(self) -> None:
        """Handle every frame already waiting (an in-process TCU, pumped by the plant)."""
        recv, handle_data = self._recv, self.handle_data
        while (item := recv(0.0)) is not None:
            if isinstance(item, tuple):
                handle_data(item[0], item[1], self.tick * self.cycle)  # (tick_time, written out: every frame)
            else:
                self.handle(item, self.tick_time)

    def handle(self, msg: can.Message, now: float) -> bool:
        """Take one frame; a SIM_SYNC tick is answered at once. True if the frame was the plant's (even a duplicate
        or a rejected one: the plant is alive), False for others (e.g. the TCU's own, looped back)."""
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id \
                or msg.is_fd != (msg.arbitration_id in self.rx.codec.fd):
            status, _ = self.rx.take(msg, now)  # not ours, or one of ours in the other frame format: rejected
            return status != IGNORED
        return self.handle_data(msg.arbitration_id, bytes(msg.data), now)

    def handle_data(self, frame_id: int, data: bytes, now: float) -> bool:
        """:meth:`handle` of a data frame with an 11-bit ID (in its message's format), given by its ID and data."""
        stamp = self.tick * self.cycle + self.cycle if self.lockstep else now  # tick_time + cycle
        status, frame = self.rx.take_data(frame_id, data, stamp)
        if status not in (NEW, DUPLICATE):
            return status != IGNORED
        assert frame is not None  # NEW and DUPLICATE come decoded
        if self.heard_at is None:
            self.heard_at = now
        if frame.name != self._sync_name:
            if status == NEW:
                self._taken_in[frame.name] = self.tick + 1
                if self._on_taken is not None:
                    self._on_taken(frame_id, data, stamp)
                if self._pending is not None and not self._missing(self._pending):  # its tick came first
                    self._answer_tick(self._pending)
                    self._answered_early = True
            return True
        tick = int(frame.values[self._tick_name])
        if status == NEW and self._on_taken is not None and tick != self.probe:
            self._on_taken(frame_id, data, stamp)
        if tick == self.probe:
            if self._answered != self.probe:
                self._reset()
            self.rx.states[self._sync_name].forget()  # the plant's ticks restart their counter after the handshake
        if tick == self._answered:  # a repeated tick (its answer was lost or late): the same frames again
            if self._answered_early:  # the tick of a re-sent period whose frame just completed it: answered
                self._answered_early = False
                return True
            self.answers_resent += self._answer_sends > 0
            self._answer_sends += 1
            for frame_id, data in self._answer:
                self._send(frame_id, data)
            return True
        if self._answered not in (None, self.probe) and tick < self._answered:
            return True  # a repeat of an older tick: answered long ago
        if status == DUPLICATE and tick != self._pending:
            return True
        if self._answered is not None and tick != self.tick + 1 and self._pending not in (tick, tick - 1) \
                and not self._confirmed(tick):
            return True
        if self._answered is not None and not self._complete(tick):
            return True  # answered when the missing frames come (late, or with the plant's re-send)
        self._answer_tick(tick)
        return True

    def _answer_tick(self, tick: int) -> None:
        """Run the control step of ``tick`` and send its answer (kept for the tick's repeats)."""
        self._pending, self._answered_early, self._unconfirmed = None, False, None
        if self.lockstep and tick > self.tick + 1:  # ticks missed: the frames taken since are this tick's period's
            since, now = self.tick_time, tick * self.cycle
            for state in self.rx.states.values():
                if state.last_time is not None and state.last_time > since:
                    state.last_time = now
        self.tick = tick
        if not self.lockstep:  # a tick with no probe before it: the plant's time base from now on
            log.info("SIM_SYNC seen: lock-step, answering each tick")
            self.lockstep = True
            self._restart(self.tick_time)
            self.tx.next_due_ms = dict.fromkeys(self.tx.next_due_ms,
                                                self.tick * self.codec.cycle_time_ms(self._cmd_name))
            self._taken_in = dict.fromkeys(self._taken_in, tick)
            for state in self.rx.states.values():
                if state.last_time is not None:
                    state.last_time = self.tick_time
        self._answer = self._step(self.tick_time, tick & 0xFF)
        for frame_id, data in self._answer:
            self._send(frame_id, data)
        self._answered, self._answer_sends = tick, 1

    def _confirmed(self, tick: int) -> bool:
        """Whether ``tick``, new and not the one after the last answered, may be answered: only when the tick before
        it came too (the plant went on while the TCU missed its ticks, e.g. under a flood that overran its receive
        queue). A single such tick is held: it may be a random frame that passed CRC and counter (the protection's
        residual error), which answered would make every tick of the plant's look old, and stop the run."""
        if self._unconfirmed != tick - 1:
            self._unconfirmed = tick
            log.info("tick %d after tick %d: held until the next tick confirms it", tick, self.tick)
            return False
        log.warning("tick %d after tick %d: %d tick(s) of the plant's never seen; going on from the plant's tick",
                    tick, self.tick, tick - self.tick - 1)
        self.ticks_missed += tick - self.tick - 1
        return True

    def _missing(self, tick: int) -> list[str]:
        """The plant messages due at ``tick`` (each on its DBC cycle from tick 0) whose frame of that tick has not
        come since the last tick answered: the one whose counter is the tick's (counters restart at tick 0, +1 per
        frame), so a frame is placed in its period whatever ticks the TCU missed or saw late (and an old frame
        whose counter the tick's has come round to again is not taken for it)."""
        if self._due_of is not self.rx:  # (name, every, state) of the messages due, looked up once per monitor
            self._due_of, self._due = self.rx, [(name, every, self.rx.states[name])
                                                for name, every in self._due_every.items()]
        taken_in, since = self._taken_in, self.tick + 1
        return [name for name, every, state in self._due if tick % every == 0 and (
            taken_in.get(name) != since or state.last_counter != (tick // every) % state.counter_modulus)]

    def _complete(self, tick: int) -> bool:
        """Whether every plant frame due at ``tick`` came in its period; if not, whether the tick has been seen
        ``SIGHTS_BEFORE_INCOMPLETE`` times (then it is answered anyway, and counted). An incomplete tick stays
        pending: the frame that completes it (one delivered after the tick, or the plant's re-send) answers it."""
        self._pending_sights = self._pending_sights + 1 if tick == self._pending else 1
        self._pending = tick
        missing = self._missing(tick)
        if not missing:
            self._pending = None
            if self._outage and any(tick % self._due_every[name] == 0 for name in self._outage):
                log.warning("tick %d: %s back after %d tick(s) answered with the last values", tick,
                            ", ".join(sorted(self._outage)), self._incomplete_run)
                self._incomplete_run, self._outage = 0, set()
            return True
        if self._pending_sights < SIGHTS_BEFORE_INCOMPLETE:
            log.info("tick %d: %s missing, waiting for it (late, or re-sent)", tick, ", ".join(missing))
            return False
        # one line when an outage starts and one when its message is back (a dropped message would log each tick
        # it is due otherwise); a message missing anew within it gets its own line
        log.log(logging.DEBUG if self._outage.issuperset(missing) else logging.WARNING,
                "tick %d seen %d times without %s: answered with the last values", tick, self._pending_sights,
                ", ".join(missing))
        self._outage.update(missing)
        self._incomplete_run += 1
        self.incomplete_answers += 1
        self._pending = None
        return True

    def _reset(self) -> None:
        """Prepare the answer to the plant's presence probe from a clean state, so every run starts alike.
        Repeated probes (the plant probes until it hears the answer) get the same answer, byte for byte: the
        counters restart once, and the tick-0 answer follows the probe answer's counter."""
        log.info("lock-step presence probe: reset and answer")
        self.lockstep = True
        self.rx = RxMonitor(self.codec, self._receives)
        self.tx = TxScheduler(self.codec, self._sends)
        self.tick = -1  # the next tick is tick 0
        self._taken_in, self._unconfirmed = {}, None
        self._restart(self.tick_time)
        cmd = self._cmd_name
        self._answer = [(self.tx.ids[cmd], self.tx.data(cmd, {self._echo_name: self.probe & 0xFF}))]
        self._answered, self._answer_sends = self.probe, 0
        self._pending, self._pending_sights, self._answered_early, self._incomplete_run = None, 0, False, 0
        self._outage = set()
