"""The lockstep protocol's two ends against each other on the in-process bus, on a fake clock (no wall time
waited): a clean run, a lost answer re-sent byte for byte without a new control step, a tick given up after its
re-sends, the presence probe resetting the TCU (a second run gives the first run's frames), a silent TCU (peer
lost, no TCU at all: peer timeout), a plant frame lost (the tick waits for the re-sent period)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from dsg_hil.protocol import Codec, TxScheduler, load_dbc
from dsg_hil.protocol.local import LocalBus, local_pair
from dsg_hil.protocol.lockstep import (RETRY_FIRST_S, LockstepMaster, LockstepResponder, PeerLost, PeerTimeout,
                                       probe_tick)

USES = {"SIM_SYNC": ("Tick",), "PLANT_SPEEDS": ("ClutchInputSpeed",), "TCU_CMD": ("P_CL_Cmd", "SyncEcho"),
        "TCU_STATUS": ("State",)}
PLANT_DATA = "PLANT_SPEEDS"  # the one plant message of these tests, due every tick


class FakeClock:
    """Time that passes only while the master waits on an empty bus."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class Tcu:
    """A TCU node behind a responder: each step commands the last ClutchInputSpeed / 1000 as P_CL_Cmd, and reports
    its steps since the last restart as State (TCU_STATUS when due). ``drop(frame_id, data)``: frames it sends that
    are lost."""

    def __init__(self, codec: Codec, bus, drop: Callable[[int, bytes], bool] = lambda i, d: False) -> None:
        self.steps: list[float] = []
        self.restarts: list[float] = []
        self.count = 0  # steps since the last restart (its controller's state)
        self.sent: list[tuple[int, bytes]] = []  # every frame it put on the bus, lost ones included

        def send(frame_id: int, data: bytes) -> None:
            self.sent.append((frame_id, data))
            if not drop(frame_id, data):
                bus.send_data(frame_id, data)

        self.link = LockstepResponder(codec, ["SIM_SYNC", PLANT_DATA], ["TCU_CMD", "TCU_STATUS"], [PLANT_DATA],
                                      step=self.step, restart=self.restart, send=send, recv=bus.recv_data)

    def restart(self, now: float) -> None:
        self.restarts.append(now)
        self.count = 0

    def step(self, now: float, echo: int) -> list[tuple[int, bytes]]:
        self.steps.append(now)
        self.count += 1
        speed = self.link.rx.values(PLANT_DATA).get("ClutchInputSpeed", 0.0)
        tx, frames = self.link.tx, []
        due = tx.due(now)
        if "TCU_STATUS" in due:
            frames.append((tx.ids["TCU_STATUS"], tx.data("TCU_STATUS", {"State": self.count % 16})))
        frames.append((tx.ids["TCU_CMD"], tx.data("TCU_CMD", {"P_CL_Cmd": speed / 1000.0, "SyncEcho": echo})))
        return frames


class Plant:
    """A plant node behind a master: each tick it sends PLANT_SPEEDS (ClutchInputSpeed = 10 x tick) and the tick.
    ``used``: the TCU's frames the master handed over, (period time, name, values), in order."""

    def __init__(self, codec: Codec, bus, clock: FakeClock, drop: Callable[[int, bytes], bool] = lambda i, d: False):
        self.bus, self.clock, self.drop = bus, clock, drop
        self.tx = TxScheduler(codec, [PLANT_DATA])
        self.used: list[tuple[float, str, dict[str, float]]] = []
        self.link = LockstepMaster(codec, ["TCU_CMD", "TCU_STATUS"], self.send, self.recv,
                                   lambda frame, item, t: self.used.append((t, frame.name, frame.values)), clock)

    def send(self, frame_id: int, data: bytes, stamp: float) -> None:
        if not self.drop(frame_id, data):
            self.bus.send_data(frame_id, data)

    def recv(self, timeout: float):
        item = self.bus.recv_data(0.0)
        if item is None:  # nothing waiting: the wait runs its course on the fake clock
            self.clock.t += timeout
        return item

    def run(self, ticks: int, pump: Callable[[], None], reply_timeout: float = 5.0) -> list[bool]:
        link = self.link
        link.handshake(60.0, pump)
        answered = []
        for tick in range(ticks):
            t = tick * link.period
            link.start(tick)
            data = self.tx.data(PLANT_DATA, {"ClutchInputSpeed": 10.0 * tick})
            self.send(self.tx.ids[PLANT_DATA], data, t)
            link.keep(self.tx.ids[PLANT_DATA], data, t)
            tick_data = link.tick_data()
            self.send(link.sync_id, tick_data, t)
            link.keep(link.sync_id, tick_data, t)
            pump()
            answered.append(link.answer(t, reply_timeout, pump))
        return answered


@pytest.fixture(scope="module")
def codec() -> Codec:
    return Codec(load_dbc(), USES)


BUSES: list[LocalBus] = []  # shut down at the end of the module


@pytest.fixture(scope="module", autouse=True)
def _shutdown():
    yield
    for bus in BUSES:
        bus.shutdown()


def pair(codec: Codec, plant_drop=lambda i, d: False, tcu_drop=lambda i, d: False) -> tuple[Plant, Tcu, FakeClock]:
    plant_bus, tcu_bus = local_pair("lockstep-test")
    BUSES.extend((plant_bus, tcu_bus))
    clock = FakeClock()
    return Plant(codec, plant_bus, clock, plant_drop), Tcu(codec, tcu_bus, tcu_drop), clock


def nth(frame_id: int, wanted: set[int]) -> Callable[[int, bytes], bool]:
    """Lose the n-th frames (from 1) of ``frame_id``."""
    seen = [0]

    def drop(i: int, data: bytes) -> bool:
        if i != frame_id:
            return False
        seen[0] += 1
        return seen[0] in wanted
    return drop


TICKS = 25


@pytest.fixture(scope="module")
def clean(codec):
    plant, tcu, clock = pair(codec)
    assert plant.run(TICKS, tcu.link.pump) == [True] * TICKS
    return plant, tcu, clock


def test_the_probe_is_the_dbcs_value(codec):
    assert probe_tick(codec) == 0xFFFFFFFF


def test_a_clean_run_answers_each_tick_once_with_no_wall_time(clean):
    plant, tcu, clock = clean
    link = plant.link
    assert clock.t == 0.0 and link.probes == 1 and not link.retries and link.unanswered_ticks == 0
    assert tcu.restarts == [-link.period] and tcu.link.lockstep  # reset by the probe: the next tick is tick 0
    assert tcu.steps == [tick * link.period for tick in range(TICKS)] and tcu.link.answers_resent == 0
    commands = [(t, values) for t, name, values in plant.used if name == "TCU_CMD"]
    assert [values["SyncEcho"] for _, values in commands] == list(range(TICKS))
    # the answer to tick k was computed from tick k's plant frame, and handed over at tick k's time
    assert all(values["P_CL_Cmd"] == pytest.approx(0.01 * tick) and t == tick * link.period
               for tick, (t, values) in enumerate(commands))
    statuses = [t for t, name, _ in plant.used if name == "TCU_STATUS"]
    assert statuses == [0.0, 0.1, 0.2]  # on its 100 ms cycle from tick 0, each before its tick's command
    assert [name for _, name, _ in plant.used[:2]] == ["TCU_STATUS", "TCU_CMD"]


def test_a_lost_answer_is_re_sent_byte_for_byte_without_a_new_step(codec, clean):
    cmd_id = codec.frame_id("TCU_CMD")
    plant, tcu, clock = pair(codec, tcu_drop=nth(cmd_id, {8}))  # the 8th TCU_CMD: the answer to tick 6
    assert plant.run(TICKS, tcu.link.pump) == [True] * TICKS
    link = plant.link
    assert link.retries == {codec.frame_id(PLANT_DATA): 1, link.sync_id: 1}  # the whole period, once
    assert clock.t == pytest.approx(RETRY_FIRST_S)  # after the first wait
    commands = [data for i, data in tcu.sent if i == cmd_id]
    assert commands[7] == commands[8] and tcu.link.answers_resent == 1  # the repeated tick: the same bytes
    assert tcu.steps == clean[1].steps and plant.used == clean[0].used  # no new step; what the plant took: alike


def test_a_tick_whose_answers_are_all_lost_is_given_up_after_its_re_sends(codec, clean):
    cmd_id = codec.frame_id("TCU_CMD")
    plant, tcu, clock = pair(codec, tcu_drop=nth(cmd_id, {8, 9, 10}))
    plant.link.retries_per_tick = 2
    answered = plant.run(TICKS, tcu.link.pump)
    assert answered == [True] * 6 + [False] + [True] * (TICKS - 7) and plant.link.unanswered_ticks == 1
    assert plant.link.retries[plant.link.sync_id] == 2 and tcu.link.answers_resent == 2
    assert clock.t == pytest.approx(RETRY_FIRST_S + 2 * RETRY_FIRST_S + 4 * RETRY_FIRST_S)  # 0.1, 0.2, 0.4 s
    assert len(tcu.steps) == TICKS  # tick 6 was stepped once; the next tick was answered as usual
    assert [v["SyncEcho"] for _, name, v in plant.used if name == "TCU_CMD"] == [k for k in range(TICKS) if k != 6]


def test_the_probe_resets_the_tcu_so_a_second_run_gives_the_first_runs_frames(codec, clean):
    plant, tcu, _ = pair(codec)
    plant.run(10, tcu.link.pump)
    again = Plant(codec, plant.bus, FakeClock())  # a new run (the plant restarted) against the same TCU
    again.run(TICKS, tcu.link.pump)
    assert len(tcu.restarts) == 2 and tcu.steps[10:] == clean[1].steps
    assert again.used == clean[0].used


def test_a_lost_probe_answer_costs_a_probe_answered_with_the_same_bytes(codec, clean):
    cmd_id = codec.frame_id("TCU_CMD")
    plant, tcu, clock = pair(codec, tcu_drop=nth(cmd_id, {1}))
    plant.run(TICKS, tcu.link.pump)
    assert plant.link.probes == 2 and len(tcu.restarts) == 1 and tcu.link.answers_resent == 1
    assert tcu.sent[0] == tcu.sent[1] and clock.t == pytest.approx(0.2)  # one probe interval
    assert plant.used == clean[0].used


def test_a_lost_plant_frame_makes_the_tick_wait_for_the_re_sent_period(codec, clean):
    plant, tcu, _ = pair(codec, plant_drop=nth(codec.frame_id(PLANT_DATA), {5}))  # tick 4's
    plant.run(TICKS, tcu.link.pump)
    assert plant.link.retries[plant.link.sync_id] == 1 and tcu.link.answers_resent == 0
    assert tcu.link.incomplete_answers == 0 and plant.used == clean[0].used


def test_a_silent_tcu_is_a_lost_peer_after_the_reply_timeout(codec):
    plant, tcu, clock = pair(codec)

    def pump() -> None:  # the TCU dies after answering tick 3
        if plant.link.tick <= 3:
            tcu.link.pump()

    with pytest.raises(PeerLost, match="TCU silent for 2 s at lock-step tick 6 .*3 ticks in a row unanswered"):
        plant.run(TICKS, pump, reply_timeout=2.0)
    # tick 4 re-sent at 0.1, 0.3, 0.7, 1.5 s, given up silent at 2 s; ticks 5 and 6 after their first wait
    assert clock.t == pytest.approx(2.0 + 2 * RETRY_FIRST_S) and plant.link.retries[plant.link.sync_id] == 4
    assert plant.link.unanswered_ticks == 2 and plant.link.unanswered_episodes == 1


@pytest.mark.parametrize("reply_timeout", [0.5, 5.0])
def test_a_tcu_that_never_repeats_an_answer_rides_out_two_lost_answers_in_a_row(codec, clean, reply_timeout):
    """An ECU written from the DBC alone answers each tick once and ignores the re-sent tick; its answers to ticks
    6 and 7 are lost. Two ticks are given up (the second after one short wait, not a second long one) and the run
    goes on: two missing commands are within the DBC's 3 cycle times, and the TCU answers new ticks."""
    cmd_id = codec.frame_id("TCU_CMD")
    sent: set[tuple[int, bytes]] = set()
    first_drop = nth(cmd_id, {8, 9})  # the answers to ticks 6 and 7 (after the probe's and tick 0-5's)

    def once(frame_id: int, data: bytes) -> bool:
        repeat = (frame_id, data) in sent
        sent.add((frame_id, data))
        return repeat or first_drop(frame_id, data)

    plant, tcu, clock = pair(codec, tcu_drop=once)
    answered = plant.run(TICKS, tcu.link.pump, reply_timeout=reply_timeout)
    assert answered == [True] * 6 + [False, False] + [True] * (TICKS - 8)
    assert plant.link.unanswered_ticks == 2 and plant.link.unanswered_episodes == 1
    assert tcu.link.answers_resent > 0  # repeats it sent and the bus lost, as an ECU that never repeats
    first_tick = min(reply_timeout, 4.5)  # the whole schedule of re-sends, or the silence reaching the timeout
    assert clock.t == pytest.approx(first_tick + (RETRY_FIRST_S if reply_timeout < 4.5 else 3 * RETRY_FIRST_S))


def test_no_tcu_is_a_peer_timeout(codec):
    plant, _, clock = pair(codec)
    with pytest.raises(PeerTimeout, match="no TCU answered the lock-step presence probe within 1 s"):
        plant.link.handshake(1.0)
    assert plant.link.probes == 5 and clock.t == pytest.approx(1.0)


def test_a_command_answering_no_tick_waiting_is_rejected_as_echo(codec, clean):
    """A TCU_CMD that passes CRC and counter but echoes tick 3 while tick 12 waits is not taken (cause "echo",
    its counter not taken either): the run is that of a clean one."""
    plant, tcu, _ = pair(codec)
    cmd_id = codec.frame_id("TCU_CMD")

    def pump() -> None:
        if plant.link.tick == 12 and not plant.link.rx.rejected:
            forged = codec.encode("TCU_CMD", {"P_CL_Cmd": 1.5, "SyncEcho": 3}, tcu.link.tx.counters["TCU_CMD"])
            plant.bus.peer.send_data(cmd_id, forged)  # from the TCU's end of the bus
        tcu.link.pump()

    plant.run(TICKS, pump)
    assert plant.link.rx.rejected == {"echo": 1} and plant.link.unanswered_ticks == 0
    assert plant.used == clean[0].used


def tick_of(data: bytes) -> int:
    return int.from_bytes(data[:4], "little")  # SIM_SYNC's Tick: bits 0-31, little endian (the DBC)


def commands(plant: Plant) -> dict[int, float]:
    """The commands the plant took, by the tick they answer: P_CL_Cmd (the TCU's copy of that tick's speed)."""
    return {int(v["SyncEcho"]): v["P_CL_Cmd"] for _, name, v in plant.used if name == "TCU_CMD"}


def test_a_tick_the_tcu_never_sees_costs_it_and_the_next_not_the_run(codec):
    """Every copy of tick 6's SIM_SYNC is lost (a receive queue overrun by a flood): the TCU, waiting for tick 6,
    hears tick 7, holds it (a lone out-of-turn tick may be a random frame), and goes on from tick 8, which
    confirms it. Every later tick is answered from its own period's frames: the frames are placed by their
    counters, not by when they came (the plant went on without the TCU for two ticks)."""
    sync = codec.frame_id("SIM_SYNC")
    plant, tcu, _ = pair(codec, plant_drop=lambda i, d: i == sync and tick_of(d) == 6)
    answered = plant.run(TICKS, tcu.link.pump, reply_timeout=60.0)
    assert answered == [True] * 6 + [False, False] + [True] * (TICKS - 8)
    assert tcu.link.ticks_missed == 2 and tcu.link.incomplete_answers == 0
    taken = commands(plant)
    assert sorted(taken) == [k for k in range(TICKS) if k not in (6, 7)]
    assert all(p == pytest.approx(0.01 * k) for k, p in taken.items())  # tick k's command from tick k's speed
    assert tcu.steps[6:] == [k * plant.link.period for k in range(8, TICKS)]  # the TCU's time is the plant's


def test_a_random_tick_that_passes_every_check_does_not_stop_the_run(codec, clean):
    """A random SIM_SYNC that passes CRC and counter (1 in 256 x 7/16 of random frames on its ID) says tick
    1,000,000 right after tick 6. Answered, it would make every later tick of the plant's look old and the TCU
    fall silent. Held, it costs the plant's next ticks whose counter it took (until the plant's counter passes it
    again: tick 7 here) and one tick to confirm the plant's going on; the run goes on on the plant's time."""
    sync = codec.frame_id("SIM_SYNC")
    forge = codec.expression_encoder("SIM_SYNC", ("tick",), {"Tick": "tick"})
    forged = forge(1_000_000, 7)  # the counter of tick 7's frame, which follows tick 6's (counters from tick 0)
    plant, tcu, _ = pair(codec)

    def pump() -> None:
        if plant.link.tick == 6 and not tcu.link.rx.states["SIM_SYNC"].rejected:
            plant.bus.send_data(sync, forged)
        tcu.link.pump()

    answered = plant.run(TICKS, pump, reply_timeout=60.0)
    assert answered == [True] * 7 + [False, False] + [True] * (TICKS - 9)
    assert tcu.link.rx.states["SIM_SYNC"].rejected == {"counter": 7}  # tick 7, sent 7 times: repeats the counter
    assert max(tcu.steps) == (TICKS - 1) * plant.link.period and tcu.link.ticks_missed == 2
    assert all(p == pytest.approx(0.01 * k) for k, p in commands(plant).items())


def test_a_tick_left_waiting_does_not_leave_the_tcu_a_tick_behind(codec, clean):
    """In a run of ticks given up the plant sends each tick twice. Tick 6's answers are all lost (tick 7 is then
    the second tick in a row given up), and every copy of tick 7's PLANT_SPEEDS is lost too: tick 7 stays waiting
    for its frame. The next frames are tick 8's, placed in tick 8 by their counter (not taken for tick 7's, which
    would answer every later tick one tick late, a tick after the plant has given it up); tick 8 is answered."""
    cmd_id, speeds = codec.frame_id("TCU_CMD"), codec.frame_id(PLANT_DATA)
    lost_answer = nth(cmd_id, {8, 9, 10, 11, 12, 13, 14})  # tick 6's answer and its 6 repeats
    tick_7 = (700).to_bytes(2, "little")  # ClutchInputSpeed 70 rpm (10 x tick), 0.1 rpm per bit
    plant, tcu, _ = pair(codec, plant_drop=lambda i, d: i == speeds and d[:2] == tick_7, tcu_drop=lost_answer)
    answered = plant.run(TICKS, tcu.link.pump, reply_timeout=60.0)
    assert answered == [True] * 6 + [False, False] + [True] * (TICKS - 8)
    assert tcu.link.ticks_missed == 0 and tcu.link.incomplete_answers == 0
    assert all(p == pytest.approx(0.01 * k) for k, p in commands(plant).items() if k != 6)
