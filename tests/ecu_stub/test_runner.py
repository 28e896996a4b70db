"""The TCU's bus side: a repeated lock-step tick or presence probe is answered with the same frames, byte for byte,
without stepping again; in real time, a plant that dies is reported as FAULT within 3 cycle times of its first
missing frame, at the first control cycle past the 3-cycle RX deadline of its last one (fake clock)."""

from __future__ import annotations

from collections.abc import Callable, Collection

import can
import pytest

from dsg_hil.sim.plant_io import PLANT_USES
from dsg_hil.protocol import Codec, TxScheduler, load_dbc
from dsg_hil.protocol.lockstep import probe_tick
from ecu_stub.calibration import TcuCalibration
from ecu_stub.controller import CreepController, TcuInputs, TcuOutputs
from ecu_stub.runner import TCU_USES, TcuRunner

SYNC_PROBE = probe_tick(Codec(load_dbc(), PLANT_USES))  # the DBC's Tick value PROBE

PLANT_DATA = ["PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER"]


class RecordingBus(can.BusABC):
    """Nothing to receive; keeps what is sent, with the fake time ``now``."""

    def __init__(self) -> None:
        super().__init__(channel="recording")
        self.now = 0.0
        self.sent: list[tuple[float, can.Message]] = []

    def send(self, msg, timeout=None):
        self.sent.append((self.now, msg))

    def _recv_internal(self, timeout):
        return None, False


@pytest.fixture()
def setup():
    db = load_dbc()
    plant_codec = Codec(db, PLANT_USES)
    bus = RecordingBus()
    tcu = TcuRunner(Codec(db, TCU_USES), bus)
    yield plant_codec, bus, tcu, []
    bus.shutdown()


def recording(on_update: Callable[[float, TcuOutputs], None]) -> type:
    """A :class:`~ecu_stub.interface.TcuController` class around ecu-stub's CreepController that tells
    ``on_update(now, outputs)`` of each step (the compiled build's controller can be neither patched nor
    subclassed). Its instances rebuild as the runner does at a lock-step start, ``type(c)(c.cal)``, with the same
    ``on_update``; ``cal`` and ``T_pred`` are the inner controller's, so the runner's checks run as with it."""

    class Recorded:
        def __init__(self, cal: TcuCalibration | None = None) -> None:
            self.inner = CreepController(cal)
            self.cal = self.inner.cal

        @property
        def T_pred(self) -> dict[str, float] | None:
            return self.inner.T_pred

        def update(self, inputs: TcuInputs, now: float) -> TcuOutputs:
            out = self.inner.update(inputs, now)
            on_update(now, out)
            return out

    return Recorded


def counting(tcu: TcuRunner, steps: list) -> None:
    tcu.controller = recording(lambda now, out: steps.append(now))(tcu.controller.cal)


def probed(plant_codec: Codec, tcu: TcuRunner) -> TxScheduler:
    """Probe the TCU (lock-step from here on); returns the plant's schedule from tick 0 (its counters restart)."""
    tcu.handle(TxScheduler(plant_codec, ["SIM_SYNC"]).frame("SIM_SYNC", {"Tick": SYNC_PROBE}), 0.0)
    return TxScheduler(plant_codec, [*PLANT_DATA, "SIM_SYNC"])


def test_repeated_probe_and_tick_get_the_same_frames_without_a_new_step(setup):
    plant_codec, bus, tcu, steps = setup
    plant = TxScheduler(plant_codec, [*PLANT_DATA, "SIM_SYNC"])
    probes = [plant.frame("SIM_SYNC", {"Tick": SYNC_PROBE}) for _ in range(2)]
    for probe in probes:  # a TCU late to the first probe hears two
        tcu.handle(probe, 0.0)
    tcu.handle(probes[1], 0.0)  # ... and a repeat of the second
    answers = [bytes(m.data) for _, m in bus.sent]
    assert len(answers) == 3 and len(set(answers)) == 1  # one answer, byte for byte: counters restart once
    probe_counter = answers[0][6] & 0x0F

    plant = TxScheduler(plant_codec, [*PLANT_DATA, "SIM_SYNC"])  # the plant's counters restart at tick 0
    counting(tcu, steps)
    for name in PLANT_DATA:
        tcu.handle(plant.frame(name, {}), 0.0)
    tick0 = plant.frame("SIM_SYNC", {"Tick": 0})
    tcu.handle(tick0, 0.0)
    first = [bytes(m.data) for _, m in bus.sent[3:]]
    assert len(steps) == 1 and len(first) == 2  # TCU_STATUS (due at 0) and TCU_CMD, last
    assert bus.sent[-1][1].arbitration_id == 0x200 and first[-1][6] & 0x0F == (probe_counter + 1) % 16
    tcu.handle(tick0, 0.0)  # the plant lost the answer and repeats the tick, byte for byte
    again = [bytes(m.data) for _, m in bus.sent[5:]]
    assert again == first and len(steps) == 1 and tcu.answers_resent == 3  # 2 probe repeats, 1 tick repeat
    counts = tcu.frame_counts()
    assert counts["by_message"]["SIM_SYNC"]["duplicates"] == 1 and counts["rejected"] == 0
    assert counts["lost"] == 0  # the tick-0 counter restart after the probes is no gap


def test_a_repeated_tick_with_a_new_counter_is_answered_without_stepping(setup):
    """A plant (not ours) that repeats a tick as a new frame still gets the same answer, not a new step."""
    plant_codec, bus, tcu, steps = setup
    plant = TxScheduler(plant_codec, [*PLANT_DATA, "SIM_SYNC"])
    tcu.handle(plant.frame("SIM_SYNC", {"Tick": SYNC_PROBE}), 0.0)
    counting(tcu, steps)
    for name in PLANT_DATA:
        tcu.handle(plant.frame(name, {}), 0.0)
    tcu.handle(plant.frame("SIM_SYNC", {"Tick": 0}), 0.0)
    n = len(bus.sent)
    tcu.handle(plant.frame("SIM_SYNC", {"Tick": 0}), 0.0)
    assert [bytes(m.data) for _, m in bus.sent[n:]] == [bytes(m.data) for _, m in bus.sent[n - 2:n]]
    assert len(steps) == 1
    for name in ("PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE"):  # due at tick 1 (10 ms)
        tcu.handle(plant.frame(name, {}), 0.0)
    tcu.handle(plant.frame("SIM_SYNC", {"Tick": 1}), 0.0)
    assert len(steps) == 2 and bus.sent[-1][1].data[4] == 1  # SyncEcho of tick 1


def test_a_tick_delivered_before_its_last_frame_is_answered_when_that_frame_comes(setup):
    """Several CPUs may deliver a frame after the tick that follows it: the tick waits, and the frame that
    completes it answers it, with no re-send needed. The tick of a re-sent period that such a frame completed is
    not answered twice; a further repeat gets the same frames again."""
    plant_codec, bus, tcu, steps = setup
    plant = probed(plant_codec, tcu)
    counting(tcu, steps)
    late = None
    for name in PLANT_DATA:
        frame = plant.frame(name, {})
        if name == "PLANT_SPEEDS":
            late = frame
        else:
            tcu.handle(frame, 0.0)
    tick0 = plant.frame("SIM_SYNC", {"Tick": 0})
    tcu.handle(tick0, 0.0)
    assert len(bus.sent) == 1 and not steps  # the probe answer only: PLANT_SPEEDS of tick 0 is missing
    tcu.handle(late, 0.0)
    answer = [bytes(m.data) for _, m in bus.sent[1:]]
    assert len(steps) == 1 and len(answer) == 2 and answer[-1][4] == 0  # TCU_STATUS, TCU_CMD echoing tick 0
    tcu.handle(tick0, 0.0)  # the tick of the re-sent period (the plant's timer ran out meanwhile)
    assert len(bus.sent) == 3
    tcu.handle(tick0, 0.0)  # asked again: the same frames
    assert [bytes(m.data) for _, m in bus.sent[3:]] == answer and len(steps) == 1
    assert tcu.frame_counts()["incomplete_answers"] == 0


class DyingPlantBus(RecordingBus):
    """A real-time plant on a fake clock: its frames at their DBC cycle times until ``dies_at``, then nothing.
    ``recv`` jumps the clock to the next frame or by the timeout."""

    def __init__(self, codec: Codec, dies_at: float) -> None:
        super().__init__()
        self.plant = TxScheduler(codec, PLANT_DATA)
        self.dies_at = dies_at
        self.pending: list[can.Message] = []
        self.last_frame_at = 0.0

    def recv(self, timeout=None):
        if not self.pending:
            due = min(self.plant.next_due.values())
            if due < self.dies_at and due <= self.now + (timeout or 0.0):
                self.now = max(self.now, due)
                self.pending = [self.plant.frame(name, {"BrakePedal": 100.0}) for name in self.plant.due(self.now)]
                self.last_frame_at = self.now
            else:
                self.now += timeout or 0.0
        return self.pending.pop(0) if self.pending else None

    def clock(self) -> float:
        return self.now


def test_realtime_tcu_reports_fault_within_three_cycles_of_the_plants_death():
    db = load_dbc()
    bus = DyingPlantBus(Codec(db, PLANT_USES), dies_at=2.0)
    tcu = TcuRunner(Codec(db, TCU_USES), bus)
    states: list[tuple[float, str]] = []
    tcu.controller = recording(lambda now, out: states.append((bus.now, out.state)))()
    tcu.run(duration=2.5, clock=bus.clock)
    bus.shutdown()
    assert states and not tcu.lockstep
    before = [s for t, s in states if t <= bus.last_frame_at]
    assert before and "FAULT" not in before  # free-running on a live plant: no fault
    fault_at = next(t for t, s in states if s == "FAULT")
    cycle = tcu.cycle
    died = bus.last_frame_at + cycle  # the first plant frame that did not come
    assert 2 * cycle < fault_at - died <= 3 * cycle + 1e-9  # RX deadline: 3 cycles after the last frame
    cmd = [(t, m) for t, m in bus.sent if m.arbitration_id == 0x200 and t >= fault_at]
    assert cmd and all(m.data[0:4] == bytes(4) for _, m in cmd)  # both clutches unpowered from then on
    status = next(m for t, m in bus.sent if m.arbitration_id == 0x210 and t >= fault_at)
    assert status.data[0] & 0x0F == 5 and status.data[4] & 0x01  # State FAULT, FaultBits: plant missing


class StallingTcuBus(DyingPlantBus):
    """A live real-time plant while the TCU's process is starved (a busy machine): every ``every`` seconds the
    TCU's clock jumps by ``stall`` in one ``recv``, the plant's frames of that time queued on its socket."""

    def __init__(self, codec: Codec, every: float, stall: float) -> None:
        super().__init__(codec, dies_at=float("inf"))
        self.every, self.stall, self.next_stall = every, stall, every
        self.stalls = 0

    def recv(self, timeout=None):
        if not self.pending and self.now >= self.next_stall:
            self.now += self.stall
            self.next_stall += self.every
            self.stalls += 1
            while min(self.plant.next_due.values()) <= self.now:
                due = min(self.plant.next_due.values())
                self.pending += [self.plant.frame(name, {"BrakePedal": 100.0}) for name in self.plant.due(due)]
        return super().recv(timeout)


def test_a_starved_realtime_tcu_controls_on_the_frames_waiting_not_on_a_fault():
    """After a stall of 8 cycle times the TCU takes every frame already waiting before its next control cycle,
    so it judges the plant by its newest frames: no FAULT while the plant is alive (it faulted when it stepped
    after the first frame of the backlog, every message but one then older than its 3-cycle deadline)."""
    db = load_dbc()
    bus = StallingTcuBus(Codec(db, PLANT_USES), every=0.3, stall=0.08)
    tcu = TcuRunner(Codec(db, TCU_USES), bus)
    states: list[str] = []
    tcu.controller = recording(lambda now, out: states.append(out.state))()
    tcu.run(duration=3.0, clock=bus.clock)
    bus.shutdown()
    assert bus.stalls >= 8 and len(states) > 100 and not tcu.lockstep
    assert "FAULT" not in states and tcu.rx.rejected_total == 0


def test_a_tick_with_plant_frames_missing_waits_for_the_re_sent_period(setup):
    """Lock-step: PLANT_SPEEDS of tick 1 lost; the TCU does not answer tick 1 until the re-sent period brings it,
    and answers a tick seen three times anyway, with the last values, counted."""
    plant_codec, bus, tcu, steps = setup
    plant = probed(plant_codec, tcu)
    counting(tcu, steps)
    period = []

    def resend(lose: Collection[str] = frozenset()) -> None:
        for msg in period:
            if msg.arbitration_id not in {plant_codec.frame_id(name) for name in lose}:
                tcu.handle(msg, 0.0)

    def send_period(tick: int, lose: Collection[str] = frozenset()) -> None:
        period[:] = [plant.frame(name, {}) for name in plant.due(tick * tcu.cycle) if name != "SIM_SYNC"]
        period.append(plant.frame("SIM_SYNC", {"Tick": tick}))
        resend(lose)

    send_period(0)
    assert len(steps) == 1
    send_period(1, lose={"PLANT_SPEEDS"})
    assert len(steps) == 1  # tick 1 unanswered: PLANT_SPEEDS of its period missing
    resend()
    assert len(steps) == 2 and tcu.frame_counts()["lost"] == 0 and tcu.incomplete_answers == 0
    assert bus.sent[-1][1].data[4] == 1  # SyncEcho of tick 1
    send_period(2, lose={"PLANT_SPEEDS"})
    resend(lose={"PLANT_SPEEDS"})
    assert len(steps) == 2  # seen twice, still waiting
    resend(lose={"PLANT_SPEEDS"})
    assert len(steps) == 3 and tcu.incomplete_answers == 1  # the third sight is answered


def test_the_tcu_fault_clock_is_the_ticks_decimal_time(setup):
    """Lock-step: the TCU's fault clock (``now``) at each tick is the tick's time from whole ms, the float of its
    decimal, as the plant's clock; the controller keeps the frames' time, tick x cycle time (not always that)."""
    plant_codec, bus, tcu, steps = setup
    plant = probed(plant_codec, tcu)
    counting(tcu, steps)
    clocks = []
    for tick in range(300):
        for name in plant.due_ms(tick * tcu.cycle_ms):
            tcu.handle(plant.frame(name, {"Tick": tick}), 0.0)
        clocks.append(tcu.now)
    assert clocks == [tick * tcu.cycle_ms / 1000 for tick in range(300)] == [tick / 100 for tick in range(300)]
    assert steps == [tick * tcu.cycle for tick in range(300)] and steps != clocks
