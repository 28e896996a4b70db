"""Lock-step that one frame cannot kill: frames dropped or corrupted in flight (a wrapper on the sending side of
python-can's virtual bus) cost a re-send, not the run, and the log stays that of a clean run; a TCU answering two
presence probes; a TCU that falls silent (peer lost); ticks given up run on the DBC's command fallback."""

from __future__ import annotations

import itertools
import time

import can
import pytest

from dsg_hil.physics.params import load_params
from dsg_hil.physics.plant import Plant
from dsg_hil.sim.plant_io import PLANT_USES
from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.protocol.lockstep import RETRIES_IN_EPISODE
from dsg_hil.sim.runner import PeerLost, PlantRunner
from dsg_hil.sim.scenario import load_scenario
from ecu_stub.runner import TCU_USES, TcuRunner

DURATION = 1.5
_channels = itertools.count()


def faulty_send(bus: can.BusABC, frame_id: int, nth: set[int], corrupt: bool = False) -> None:
    """Make ``bus`` lose (or, with ``corrupt``, flip a data bit of) the n-th frames of ``frame_id`` it sends
    (counting from 1, first transmissions and repeats alike)."""
    send, seen = bus.send, itertools.count(1)

    def lossy(msg, timeout=None):
        if msg.arbitration_id == frame_id and next(seen) in nth:
            if not corrupt:
                return None
            msg = can.Message(arbitration_id=msg.arbitration_id, data=bytes([msg.data[0] ^ 0x01, *msg.data[1:]]),
                              is_extended_id=False)
        return send(msg, timeout)

    bus.send = lossy


class LockstepPair:
    """Plant and TCU on one virtual channel, the TCU pumped in process (optionally late: ``tcu_delay`` pumps
    ignored at first, so probes queue up). ``frames`` is the plant's log: (timestamp, id, data)."""

    def __init__(self, duration: float = DURATION, tcu_delay: int = 0, plant: Plant | None = None) -> None:
        db, scenario = load_dbc(), load_scenario().with_duration(duration)
        channel = f"lockstep-{next(_channels)}"
        self.plant_bus = can.Bus(interface="virtual", channel=channel)
        self.tcu_bus = can.Bus(interface="virtual", channel=channel)
        self.frames: list[tuple[float, int, bytes]] = []
        self.runner = PlantRunner(plant or Plant(load_params()), scenario, Codec(db, PLANT_USES), self.plant_bus,
                                  listeners=(lambda m: self.frames.append((m.timestamp, m.arbitration_id,
                                                                           bytes(m.data))),))
        self.runner.retry_first_s, self.runner.retry_max_s = 0.02, 0.05  # fast retries: a test, not a bus
        self.tcu = TcuRunner(Codec(db, TCU_USES), self.tcu_bus)
        self.codec = self.runner.codec
        self.tcu_delay = tcu_delay
        self.silent_after_tick: int | None = None

    def pump(self) -> None:
        if self.tcu_delay > 0:
            self.tcu_delay -= 1
            return
        if self.silent_after_tick is not None and self.runner.tick > self.silent_after_tick:
            while self.tcu_bus.recv(timeout=0.0) is not None:  # a dead TCU: hears nothing, says nothing
                pass
            return
        self.tcu.pump()

    def run(self, reply_timeout: float = 5.0):
        try:
            return self.runner.run_lockstep(reply_timeout=reply_timeout, pump=self.pump, startup_timeout=5.0)
        finally:
            self.plant_bus.shutdown()
            self.tcu_bus.shutdown()

    def id(self, name: str) -> int:
        return self.codec.frame_id(name)


@pytest.fixture(scope="module")
def clean():
    pair = LockstepPair()
    pair.run()
    return pair


def test_clean_run_needs_no_retries(clean):
    f = clean.runner.frames()
    assert f["retries"] == 0 and f["duplicates"] == 0 and f["lost"] == 0 and f["unanswered_ticks"] == 0
    assert f["by_message"]["SIM_SYNC"]["sent"] == clean.runner.n_periods
    assert f["by_message"]["TCU_CMD"]["taken"] == clean.runner.n_periods
    assert clean.tcu.answers_resent == 0 and clean.tcu.frame_counts()["duplicates"] == 0 and f["probes"] == 1


def test_the_fault_clock_is_the_plants_counted_time():
    """The clock of the plant's fault windows is its step count in seconds: at every frame of a period, sent or
    taken, the decimal time of the period's start (as a window's start_s from a scenario reads), which a float sum
    of dt is not always."""
    pair = LockstepPair(duration=0.5)
    runner, seen = pair.runner, []
    runner.listeners = (*runner.listeners, lambda m: seen.append((runner.clock(), runner.plant.state.k)))
    pair.run()
    assert len({k for _, k in seen}) == runner.n_periods == 50
    assert all(k % runner.steps_per_period == 0 for _, k in seen)
    assert all(clock == k / 1000 for clock, k in seen)
    sums = [0.0]
    for _ in range(500):
        sums.append(sums[-1] + runner.plant.dt)
    assert any(sums[k] != k / 1000 for _, k in seen)  # a summed clock would miss some windows' edges
    assert runner.plant.state.t == 0.5


def test_a_lost_probe_answer_costs_a_probe(clean):
    pair = LockstepPair()
    faulty_send(pair.tcu_bus, pair.id("TCU_CMD"), {1})
    pair.run()
    f = pair.runner.frames()
    assert f["probes"] == 2 and f["retries"] == 0 and f["rejected"] == 0 and pair.tcu.answers_resent == 1
    assert pair.frames == clean.frames


@pytest.mark.parametrize("lose", [("TCU_CMD", "tcu", {2}), ("TCU_CMD", "tcu", {50, 51, 52}),
                                  ("SIM_SYNC", "plant", {2}), ("SIM_SYNC", "plant", {40, 41}),
                                  ("TCU_STATUS", "tcu", {3}), ("PLANT_SPEEDS", "plant", {30})])
def test_lost_frames_cost_retries_not_the_run_and_leave_the_log_unchanged(clean, lose):
    """Any frame of a period lost (TCU_CMD, TCU_STATUS, SIM_SYNC, a plant frame): the plant re-sends the period
    (the TCU does not answer a tick whose plant frames are incomplete; the plant asks again for an answer whose
    TCU_STATUS is missing), the TCU answers from what it already computed or from the complete period; the
    logged frames are those of the clean run, bit for bit."""
    name, sender, nth = lose
    pair = LockstepPair()
    faulty_send(pair.tcu_bus if sender == "tcu" else pair.plant_bus, pair.id(name), nth)
    pair.run()
    f = pair.runner.frames()
    assert pair.frames == clean.frames
    assert f["retries"] > 0 and f["by_message"]["SIM_SYNC"]["retries"] >= len(nth)
    assert f["rejected"] == 0 and f["unanswered_ticks"] == 0 and f["lost"] == 0
    if name == "TCU_CMD":  # the TCU re-sent its answers; it did not step again
        assert pair.tcu.answers_resent == len(nth)
    if name == "SIM_SYNC":  # the TCU never had those ticks: the re-sent ones were new to it, not repeats
        assert pair.tcu.answers_resent == 0 and pair.tcu.frame_counts()["by_message"]["SIM_SYNC"]["lost"] == 0
    if name == "TCU_STATUS":  # asked again: the TCU re-sent status and command, the command a duplicate
        assert pair.tcu.answers_resent == 1 and f["by_message"]["TCU_CMD"]["duplicates"] == 1
    if name == "PLANT_SPEEDS":  # re-sent with the period: nothing lost, one retry, no stale answer
        assert f["by_message"]["SIM_SYNC"]["retries"] == 1
        counts = pair.tcu.frame_counts()
        assert counts["lost"] == 0 and counts["incomplete_answers"] == 0 and pair.tcu.answers_resent == 0
    assert pair.runner.plant.state.t == DURATION  # counted: exact


def test_a_command_corrupted_in_flight_is_rejected_then_re_sent(clean):
    pair = LockstepPair()
    faulty_send(pair.tcu_bus, pair.id("TCU_CMD"), {20}, corrupt=True)
    pair.run()
    f = pair.runner.frames()
    assert f["by_message"]["TCU_CMD"]["rejected"] == {"crc": 1} and f["rejected"] == 1
    assert f["by_message"]["SIM_SYNC"]["retries"] == 1 and pair.tcu.answers_resent == 1
    assert pair.frames == clean.frames


def test_late_duplicate_answers_are_counted_not_rejected(clean):
    """A TCU that answers late (the plant has re-sent the tick meanwhile) answers twice: the second, identical
    answer is a duplicate at the plant, not a counter error."""
    pair = LockstepPair()
    original = pair.pump

    def late_pump():  # the TCU misses the first pump of tick 10 and then sees the tick twice
        if pair.runner.tick == 10 and pair.runner.retries["SIM_SYNC"] == 0:
            return
        original()

    pair.pump = late_pump
    pair.run()
    f = pair.runner.frames()
    assert f["by_message"]["SIM_SYNC"]["retries"] == 1 and f["rejected"] == 0
    assert pair.tcu.answers_resent == 1 and f["by_message"]["TCU_CMD"]["duplicates"] == 1
    assert pair.frames == clean.frames


def forge_after(bus: can.BusABC, codec: Codec, after: int, values: dict[str, float], step: int = 2) -> None:
    """After the ``after``-th TCU_CMD ``bus`` sends, put a frame on the bus that passes every end-to-end check
    (valid CRC, counter ``step`` on from the real one): a TCU_CMD with ``values``."""
    send, seen, cmd_id = bus.send, itertools.count(1), codec.frame_id("TCU_CMD")

    def forging(msg, timeout=None):
        send(msg, timeout)
        if msg.arbitration_id == cmd_id and next(seen) == after:
            counter = (codec.decode(cmd_id, bytes(msg.data)).counter + step - 1) % 16
            send(can.Message(arbitration_id=cmd_id, data=codec.encode("TCU_CMD", values, counter),
                             is_extended_id=False), timeout)

    bus.send = forging


@pytest.mark.parametrize("late", [1, 3, 200])
def test_a_command_answering_no_tick_is_rejected_as_echo(clean, late):
    """A TCU_CMD that passes CRC and counter (one step on) but echoes a tick that is not waiting (sent after the
    real answer to tick 20, so read while tick 21 waits: ``late`` + 1 ticks old) is not taken: rejected ("echo"),
    its counter not taken (the next real command, one step on, is taken), the run that of a clean one."""
    pair = LockstepPair()
    tick = 20
    forge_after(pair.tcu_bus, pair.codec, tick + 2, {"P_CL_Cmd": 1.5, "P_CH_Cmd": 1.5, "SyncEcho": (tick - late) % 256})
    pair.run()
    f = pair.runner.frames()
    assert f["by_message"]["TCU_CMD"]["rejected"] == {"echo": 1} and f["unanswered_ticks"] == 0
    assert f["lost"] == 0 and pair.frames == clean.frames


@pytest.mark.slow
def test_tcu_answering_two_presence_probes_starts_cleanly(clean):
    """Regression: a TCU slower than the probe interval answered two probes, restarting its counter on each, so
    its tick-0 answer repeated counter 0 and the run aborted. Now both probes get the same answer, byte for
    byte, and the run is that of a clean start."""
    pair = LockstepPair(tcu_delay=1)  # the first probe is heard only with the second
    pair.run()
    f = pair.runner.frames()
    assert f["rejected"] == 0 and f["by_message"]["TCU_CMD"]["duplicates"] == 1  # the second probe answer
    assert pair.frames == clean.frames


def test_silent_tcu_ends_the_run_as_peer_lost_with_the_summary_so_far():
    pair = LockstepPair(duration=5.0)
    pair.silent_after_tick = 30
    with pytest.raises(PeerLost, match=r"TCU silent for 0.3 s at lock-step tick \d+"):
        pair.run(reply_timeout=0.3)
    s, f = pair.runner.summary, pair.runner.frames()
    assert s.stop_reason == "peer_lost"
    assert 0.3 <= pair.runner.plant.state.t < 5.0 and f["by_message"]["TCU_CMD"]["taken"] == 31
    assert f["by_message"]["SIM_SYNC"]["retries"] > 0


def test_ticks_given_up_run_on_the_dbc_fallback():
    """Every answer to ticks 50-51 (50-53) lost (retries too): each tick is given up after its re-sends and counted
    (one episode);
    two missing commands are within the DBC's 3 cycle times (the last command holds), four are not (hydraulics
    unpowered: one fallback event), and control resumes."""
    results = {}
    for n_lost in (2, 4):
        pair = LockstepPair()
        pair.runner.retries_per_tick = 2
        cmd_id = pair.id("TCU_CMD")
        send = pair.tcu_bus.send

        def lossy(msg, timeout=None, send=send, pair=pair, n_lost=n_lost, cmd_id=cmd_id):
            if msg.arbitration_id == cmd_id and 50 <= pair.runner.tick < 50 + n_lost:
                return None
            return send(msg, timeout)

        pair.tcu_bus.send = lossy
        summary = pair.run()
        results[n_lost] = (pair.runner.frames(), summary)
    for n_lost, (f, _) in results.items():
        # the first tick of the run given up after its 2 re-sends, the next ones after RETRIES_IN_EPISODE
        assert f["unanswered_ticks"] == n_lost and f["unanswered_episodes"] == 1
        assert f["by_message"]["SIM_SYNC"]["retries"] == 2 + (n_lost - 1) * RETRIES_IN_EPISODE
        assert f["rejected"] == 0
    assert results[2][1].fallback_events == 0
    assert results[4][1].fallback_events == 1 and results[4][1].fallback_time_s > 0


def test_silence_summed_over_ticks_given_up_ends_the_run():
    """Ticks given up sooner than the reply timeout: the TCU's silence adds up over them, so a dead TCU still
    ends the run."""
    pair = LockstepPair(duration=5.0)
    pair.runner.retries_per_tick = 2  # a tick given up after 0.02 + 0.04 + 0.05 s
    pair.silent_after_tick = 30
    with pytest.raises(PeerLost):
        pair.run(reply_timeout=0.4)
    assert pair.runner.frames()["unanswered_ticks"] >= 2 and pair.runner.summary.stop_reason == "peer_lost"


def test_a_stalled_plant_is_no_lost_peer(clean):
    """The plant itself stalled longer than the reply timeout between two ticks (a busy machine): the answer
    waiting for it is read first, not mistaken for silence."""
    class Stalling(Plant):  # (the runner's methods are read-only in the compiled build: the plant is the seam)
        def advance(self, *args, **kwargs):
            if pair.runner.tick == 20:
                time.sleep(0.5)
            return super().advance(*args, **kwargs)

    pair = LockstepPair(plant=Stalling(load_params()))
    pair.run(reply_timeout=0.3)
    assert pair.runner.frames()["retries"] == 0 and pair.frames == clean.frames


def test_a_tcu_without_status_costs_retries_at_tick_0_only():
    """A TCU (not ours) that never sends TCU_STATUS: asked again twice at tick 0, then taken as it is."""
    pair = LockstepPair()
    faulty_send(pair.tcu_bus, pair.id("TCU_STATUS"), set(range(1, 10_000)))
    pair.run()
    f = pair.runner.frames()
    assert f["by_message"]["SIM_SYNC"]["retries"] == 2 and f["unanswered_ticks"] == 0
    assert f["by_message"]["TCU_CMD"]["taken"] == pair.runner.n_periods
