"""Real-time mode with a scripted TCU and a fake clock: commands used as they arrive, unpowered hydraulics
when TCU_CMD misses its deadline (3 cycle times), control resumes when commands return."""

from __future__ import annotations

import re

import can
import pytest

from dsg_hil.physics.params import load_params
from dsg_hil.physics.plant import Plant
from dsg_hil.sim.plant_io import PLANT_USES
from dsg_hil.protocol import Codec, TxScheduler, load_dbc
from dsg_hil.sim.runner import PlantRunner
from dsg_hil.sim.scenario import parse_scenario

SCENARIO = """
duration_s = 3.0
[initial]
T_clutch_c = 80.0
[[driver]]
t_s = 0.0
brake = 1.0
"""


class ScriptedBus(can.BusABC):
    """A bus whose recv advances a fake clock; the 'TCU' sends 0.6 MPa on CL every 10 ms except in a gap."""

    def __init__(self, codec: Codec, gap: tuple[float, float]) -> None:
        super().__init__(channel="scripted")
        self.now = 0.0
        self.gap = gap
        self.tx = TxScheduler(codec, ["TCU_CMD"])
        self.pending: list[can.Message] = []
        self.sent: list[can.Message] = []

    def send(self, msg, timeout=None):
        self.sent.append(msg)

    def recv(self, timeout=None):  # no real waiting: the clock jumps by the timeout
        if not self.pending:
            self.now += timeout or 0.0
            if not self.gap[0] <= self.now < self.gap[1]:
                for _ in self.tx.due(self.now):
                    self.pending.append(self.tx.frame("TCU_CMD", {"P_CL_Cmd": 0.6}, timestamp=self.now))
        return self.pending.pop(0) if self.pending else None

    def _recv_internal(self, timeout):
        raise NotImplementedError

    def clock(self) -> float:
        return self.now


def test_command_timeout_falls_back_and_recovers(caplog):
    db = load_dbc()
    codec = Codec(db, PLANT_USES)
    bus = ScriptedBus(codec, gap=(1.0, 2.0))
    pressures = []

    class Recorded(Plant):  # each step's clutch pressure (the runner's methods are read-only in the compiled build)
        def advance(self, *args, **kwargs):
            out = super().advance(*args, **kwargs)
            pressures.append((self.state.t, self.state.P_CL))
            return out

    runner = PlantRunner(Recorded(load_params()), parse_scenario(SCENARIO), codec, bus)
    summary = runner.run_realtime(clock=bus.clock)
    bus.shutdown()
    P = dict((round(t, 3), p) for t, p in pressures)
    assert P[0.99] == pytest.approx(0.6e6, rel=0.01)  # commanded pressure reached
    assert P[1.5] < 0.01e6  # unpowered: decayed towards zero within the gap
    assert P[2.9] == pytest.approx(0.6e6, rel=0.01)  # control resumed
    assert summary.fallback_events == 1
    # invalid from 30 ms after the last command before the gap (0.99 s) to the first after it (2.0 s)
    assert summary.fallback_time_s == pytest.approx(2.0 - (0.99 + 0.03), abs=0.003)
    # the warning: the silence measured on the clock, from the last command (0.99 s), at the first 1-ms step's check
    # after the 30-ms limit
    found = [re.search(r"missing for ([0-9.]+) ms \(limit 30 ms; previous check ([0-9.]+) ms before\)", r.message)
             for r in caplog.records]
    (silent, since_check), = [(float(m[1]), float(m[2])) for m in found if m]
    assert since_check == pytest.approx(1.0, abs=0.05)
    assert 30.0 < silent <= 30.0 + since_check + 0.05
    names = {codec.message(n).frame_id for n in ("PLANT_ENGINE", "PLANT_OIL_TEMP", "SIM_TRUTH_CL")}
    assert names <= {m.arbitration_id for m in bus.sent}
    engine = [m.timestamp for m in bus.sent if m.arbitration_id == codec.frame_id("PLANT_ENGINE")]
    assert len(engine) == pytest.approx(300, abs=2)  # 10 ms cycle over 3 s


def test_a_plant_that_never_hears_a_tcu_counts_that_fallback_and_reports_every_10_s():
    """Issue 35, item 10: 'events: 0' with 'time_s' the whole run for a plant that never heard a TCU, and a real-time
    run printed its line at t = 0 only (its 10-s check one step late, after the run of 10 s had ended). Now one
    fallback event, at the command's deadline, and the lines of a lock-step run: at t = 10.0 of 10 s."""
    codec = Codec(load_dbc(), PLANT_USES)
    bus = ScriptedBus(codec, gap=(0.0, float("inf")))  # no TCU_CMD ever
    lines: list[str] = []
    scenario = parse_scenario(SCENARIO.replace("duration_s = 3.0", "duration_s = 10.0"))
    runner = PlantRunner(Plant(load_params()), scenario, codec, bus, progress=lines.append)
    summary = runner.run_realtime(clock=bus.clock)
    bus.shutdown()
    assert summary.fallback_events == 1
    assert summary.fallback_time_s == pytest.approx(10.0, abs=0.002)
    assert [float(re.match(r"t=\s*([0-9.]+)/10 s", line)[1]) for line in lines] == [10.0], lines
