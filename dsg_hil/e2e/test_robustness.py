"""Robustness on a real SocketCAN vcan0: a flood of random frames during a creep, a TCU killed and restarted under
a real-time plant, a plant killed under a TCU. Judged on the processes' own records (the plant's log, summary and
warnings; candump's kernel timestamps), by causality and cycle times, never on wall-clock figures."""

from __future__ import annotations

import inspect
import json
import re
import shutil
import signal
import subprocess
import time
from itertools import pairwise

import can
import pytest

from dsg_hil.loop import plant_for
from dsg_hil.plant_io import PLANT_USES, SYNC_PROBE
from dsg_hil.protocol import Codec
from dsg_hil.protocol.codec import FrameError
from dsg_hil.protocol.e2e import MAX_DELTA
from ecu_stub.runner import TCU_RX, TCU_USES

from .conftest import BUS, STARTUP, TCU_IDLE_EXIT, Candump, console, finish_while_progressing, parse_candump

pytestmark = pytest.mark.vcan
FLOOD_FRAMES = 100_000
FLOOD_BATCH = 10_000  # cangen runs in batches while the creep runs: frames counted are whole batches
MAX_FLOOD_RUNS = 50  # creeps at most (a native lock-step creep may end before cangen sent one batch)
FALLBACK = re.compile(r"t=([0-9.]+) s: TCU_CMD missing")
RESUMED = re.compile(r"t=([0-9.]+) s: valid TCU_CMD again")


@pytest.fixture(scope="module")
def cangen():
    path = shutil.which("cangen")
    if path is None:
        pytest.fail("cangen (can-utils) is missing")
    return path


def wait_for(predicate, timeout: float, what: str) -> None:
    """Orchestration only (when to inject a fault); nothing is judged on these waits."""
    end = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < end, f"gave up waiting for {what}"
        time.sleep(0.05)


def first_tick(db, plant, timeout: float = STARTUP) -> None:
    """Wait until the lock-step run proper has begun: the first PLANT_ENGINE frame (after the presence handshake)."""
    engine = db.get_message_by_name("PLANT_ENGINE").frame_id
    with can.Bus(interface="socketcan", channel="vcan0", can_filters=[{"can_id": engine, "can_mask": 0x7FF}]) as bus:
        end = time.monotonic() + timeout
        while bus.recv(timeout=1.0) is None:
            assert plant.poll() is None and time.monotonic() < end, "the plant never started its run"


def start_plant(outdir, name, mode, duration, *extra):
    log, summary = outdir / f"{name}.plant.log", outdir / f"{name}.summary.json"
    proc = subprocess.Popen([console("dsg-hil"), "plant", *BUS, "--mode", mode, "--duration", str(duration),
                             "--log", str(log), "--summary", str(summary), *extra],
                            stderr=subprocess.PIPE, text=True)
    return proc, log, summary


def start_tcu(*extra):
    tcu = subprocess.Popen([console("ecu-stub"), *BUS, *extra], stderr=subprocess.PIPE, text=True)
    assert "listening on socketcan:vcan0" in tcu.stderr.readline()
    return tcu


def stop(proc, timeout: float = 60.0) -> str:
    try:
        return proc.communicate(timeout=timeout)[1] or ""
    finally:
        if proc.poll() is None:
            proc.kill()


def on_bus(dump: Candump, ident: int) -> int:
    """How many frames of ``ident`` candump has recorded so far (its file lags by a buffer: fine here)."""
    return dump.path.read_text().count(f" {ident:03X}#")


def plant_times(frames):
    """Frames of the plant's log in the plant's time [s from its first frame] (its stamps: start + step time)."""
    t0 = frames[0][0]
    return [(t - t0, ident, data) for t, ident, data in frames]


# ---- a flood of random frames during a lock-step creep ------------------------------------------------------------
def flooded_creep(db, outdir, name, duration, cangen, target):
    """One lock-step creep as the ``lockstep`` run, cangen sending random IDs, DLCs and data as fast as it can
    (``-g 0``, ENOBUFS ignored) from its first tick until ``target`` frames are sent or the creep ends; candump
    records the frames on the DBC's IDs (the ones a node may take; all of them would starve it: it kept 54k of
    920k). Returns what the test judges, ``injected`` counting whole batches sent while the creep ran."""
    dump = Candump(outdir / f"{name}.candump.log", [m.frame_id for m in db.messages])
    tcu = start_tcu("--idle-exit", TCU_IDLE_EXIT)
    plant, log, summary = start_plant(outdir, name, "lockstep", duration, "--reply-timeout", "60")
    batches = 0
    try:
        first_tick(db, plant)
        while plant.poll() is None and batches * FLOOD_BATCH < target:
            gen = subprocess.run([cangen, "vcan0", "-g", "0", "-I", "r", "-L", "r", "-D", "r", "-i",
                                  "-n", str(FLOOD_BATCH)], capture_output=True, text=True, timeout=600)
            assert gen.returncode == 0, gen.stderr
            batches += plant.poll() is None  # whole batches sent while the creep ran
        plant_err = finish_while_progressing(plant, log)  # the rest of the creep: every tick must run
        tcu_err = stop(tcu, timeout=120)
    finally:
        for proc in (plant, tcu):
            if proc.poll() is None:
                proc.kill()
        recorded = dump.stop()
    (outdir / f"{name}.plant.stderr").write_text(plant_err)
    (outdir / f"{name}.tcu.stderr").write_text(tcu_err)
    return {"name": name, "plant_rc": plant.returncode, "tcu_rc": tcu.returncode, "plant_err": plant_err,
            "tcu_err": tcu_err, "injected": batches * FLOOD_BATCH, "summary": json.loads(summary.read_text()),
            "log": log, "bus": sorted(recorded, key=lambda f: f[0])}


@pytest.fixture(scope="module")
def flood(db, outdir, duration, cangen, lockstep):
    """FLOOD_FRAMES random frames (and a batch more) over as many flooded creeps as it takes: one under
    emulation, several where the lock-step loop runs faster than cangen can fill it."""
    runs: list[dict] = []
    while sum(run["injected"] for run in runs) < FLOOD_FRAMES and len(runs) < MAX_FLOOD_RUNS:
        left = FLOOD_FRAMES + FLOOD_BATCH - sum(run["injected"] for run in runs)
        runs.append(flooded_creep(db, outdir, f"flood{len(runs)}", duration, cangen, left))
    return runs


def sim_sync_tick(db, data: bytes) -> int:
    return int(db.get_message_by_name("SIM_SYNC").decode(data, decode_choices=False)["Tick"])


def first_forgery(db, flood_bus, plant_sent):
    """The first random frame the end-to-end protection cannot tell from a real one, with the lock-step tick it
    came in (or None): on a message the plant sends and the TCU reads, passing the TCU's stateless checks (DLC,
    CRC, ranges) and its counter check (a step of 1 to MAX_DELTA from the last real frame of its message), yet
    not a frame the plant sent (its log: ``plant_sent``). Such a frame is the protection's residual error (CRC-8:
    1/256 of the frames with the right DLC, and 7/16 of those also pass the counter check), about 0.1 per
    100,000-frame flood; the test names it when it happens. (A random TCU_CMD would also need its tick's echo,
    1/256 more: not looked for.)"""
    real = {(ident, data) for _, ident, data in plant_sent}
    plant_ids = {db.get_message_by_name(name).frame_id for name in TCU_RX}  # all sent by the plant
    codec = Codec(db, TCU_USES)
    sync = db.get_message_by_name("SIM_SYNC").frame_id
    tick, last = -1, {}
    for t, ident, data in flood_bus:
        if ident not in plant_ids:
            continue
        if (ident, data) in real:
            last[ident] = codec.decode(ident, data).counter
            if ident == sync:
                tick = sim_sync_tick(db, data)
            continue
        try:
            frame = codec.decode(ident, data)
        except FrameError:
            continue
        if ident == sync and int(frame.values["Tick"]) == SYNC_PROBE:  # presence probes: not in the plant's log
            continue
        if ident in last and not 1 <= (frame.counter - last[ident]) % 16 <= MAX_DELTA:
            continue  # the counter check refuses it
        return tick, t, ident, data
    return None


def control_view(db, frames):
    """The plant's log as the loop sees it: every frame as it is, but TCU_STATUS without its FaultBits (and
    CRC), which report the rejected frames: under a flood they differ from an undisturbed run, as they must."""
    status = db.get_message_by_name("TCU_STATUS")
    return [(ident, data) if ident != status.frame_id else
            (ident, tuple(v for k, v in status.decode(data, decode_choices=False).items()
                          if k not in ("FaultBits", "CRC")))
            for _, ident, data in frames]


def test_flood_neither_process_fails(flood):
    injected = sum(run["injected"] for run in flood)
    assert injected >= FLOOD_FRAMES, f"only {injected} random frames in {len(flood)} creeps"
    for run in flood:
        assert run["plant_rc"] == 0, run["plant_err"]
        assert run["tcu_rc"] == 0, run["tcu_err"]
        frames = run["summary"]["frames"]
        print(f"{run['name']}: {run['injected']} random frames injected; {len(run['bus'])} frames on the DBC's IDs "
              f"recorded; {frames['by_message']['SIM_SYNC']['sent']} ticks, {frames['unanswered_ticks']} "
              f"unanswered after their re-sends (run on the fallback), {frames['retries']} frames re-sent, "
              f"fallback events {run['summary']['command_fallback']['events']}")
        assert run["summary"]["stop_reason"] == "end_of_record"  # every tick of the creep ran: no stall


def test_flood_rejects_are_counted_by_cause(flood):
    """The plant's summary and the TCU's closing line count what each rejected, by cause."""
    for run in flood:
        frames = run["summary"]["frames"]
        causes = {name: m["rejected"] for name, m in frames["by_message"].items() if m["rejected"]}
        print(f"{run['name']}: plant rejected {frames['rejected']}: {causes}")
        assert frames["rejected"] == sum(sum(c.values()) for c in causes.values()), causes
        assert set(causes) <= {"TCU_CMD", "TCU_STATUS"}  # the plant judges only what it reads
        closing = re.search(r"rejected (\d+)(?: \(([^)]*)\))?, lost", run["tcu_err"])
        assert closing, run["tcu_err"]
        tcu_causes = {k: int(n) for k, n in (item.rsplit(" ", 1) for item in (closing[2] or "").split(", ") if item)}
        print(f"{run['name']}: TCU rejected {closing[1]}: {tcu_causes}")
        assert int(closing[1]) == sum(tcu_causes.values())
    assert sum(run["summary"]["frames"]["rejected"] for run in flood) > 0  # the flood reached the plant's IDs
    assert sum(int(re.search(r"rejected (\d+)", run["tcu_err"])[1]) for run in flood) > 0  # and the TCU's


def test_flood_no_corrupt_command_taken(db, flood, lockstep):
    """Every TCU_CMD the plant took (its log) carries a valid CRC, a counter step the E2E rules accept and its
    tick's echo, one per tick but the unanswered ones (counted); and the plant's log is the one of the undisturbed
    lock-step run, byte for byte but the TCU's FaultBits (:func:`control_view`): no random frame was taken. Only a
    random frame that passes every check a receiver can make (see ``first_forgery``) may change the run, and then
    not before the tick it came in (less one: delivery order across CPUs)."""
    for run in flood:
        check_flooded_run(db, run, lockstep)


def check_flooded_run(db, run, lockstep) -> None:
    cmd, sync = db.get_message_by_name("TCU_CMD"), db.get_message_by_name("SIM_SYNC")
    frames = plant_times(parse_candump(run["log"]))
    commands = [data for _, ident, data in frames if ident == cmd.frame_id]
    counts = run["summary"]["frames"]
    assert len(commands) == counts["by_message"]["SIM_SYNC"]["sent"] - counts["unanswered_ticks"] > 100
    codec = Codec(db, PLANT_USES)
    first = codec.decode(cmd.frame_id, commands[0]).counter
    tick, previous = None, first - 1
    for _, ident, data in frames:  # the log's order is the plant's: a tick, then the command it took for it
        if ident == sync.frame_id:
            tick = sim_sync_tick(db, data)
        elif ident == cmd.frame_id:
            frame = codec.decode(cmd.frame_id, data)  # the plant's own checks: raises FrameError on a CRC/DLC fault
            assert tick is not None and int(frame.values["SyncEcho"]) == tick & 0xFF, (tick, frame.values)
            assert 1 <= (frame.counter - previous) % 16 <= MAX_DELTA, (tick, previous, frame.counter)
            previous = frame.counter
    status = db.get_message_by_name("TCU_STATUS")
    reported = sum(1 for _, ident, data in frames
                   if ident == status.frame_id and status.decode(data, decode_choices=False)["FaultBits"])
    print(f"{run['name']}: TCU_STATUS taken by the plant reporting rejected frames (FaultBits): {reported}")
    reference = control_view(db, parse_candump(run["log"].parent / "lockstep.plant.log"))
    taken = control_view(db, frames)
    if taken == reference:
        return
    forgery = first_forgery(db, run["bus"], frames)
    assert forgery is not None, "the flood changed the run, and no random frame could pass a receiver's checks"
    tick, t, ident, data = forgery
    print(f"{run['name']}: random frame {ident:03X}#{data.hex().upper()} at {t:.6f} (tick {tick}) passes every "
          f"receiver check: the run may differ from tick {tick} on")
    end = next((i for i, (ident, data) in enumerate(reference)
                if ident == sync.frame_id and sim_sync_tick(db, data) >= max(tick - 1, 0)), len(reference))
    assert taken[:end] == reference[:end], "the run changed before the random frame that could pass came in"


# ---- the TCU killed and restarted under a real-time plant ---------------------------------------------------------
@pytest.fixture(scope="module")
def tcu_killed(db, outdir):
    """A real-time creep whose TCU is killed (SIGKILL) once its commands flow and started again a second later;
    the plant is stopped (SIGTERM: its summary and log are written) once the new TCU's commands flow."""
    cmd_id = db.get_message_by_name("TCU_CMD").frame_id
    dump = Candump(outdir / "tcu_kill.candump.log")
    tcu, second = start_tcu(), None
    plant, log, summary = start_plant(outdir, "tcu_kill", "realtime", 600)  # stopped below
    try:
        wait_for(lambda: on_bus(dump, cmd_id) >= 50, STARTUP, "the TCU's commands")
        tcu.send_signal(signal.SIGKILL)
        tcu.wait(timeout=30)
        before = on_bus(dump, cmd_id)
        time.sleep(1.0)
        second = start_tcu("--idle-exit", "2")
        wait_for(lambda: on_bus(dump, cmd_id) >= before + 100, STARTUP, "the restarted TCU's commands")
        plant.send_signal(signal.SIGTERM)
        plant_err = stop(plant, timeout=120)
        stop(second)
    finally:
        for proc in (plant, tcu, second):
            if proc is not None and proc.poll() is None:
                proc.kill()
        recorded = dump.stop()
    (outdir / "tcu_kill.plant.stderr").write_text(plant_err)
    data = json.loads(summary.read_text())
    assert data["stop_reason"] == "terminated", plant_err
    return data, plant_times(parse_candump(log)), plant_err, recorded


def test_tcu_kill_detected_within_3_cycles_then_recovers(db, tcu_killed):
    """In the plant's own time (its log's stamps and its warnings): the fallback comes within 3 TCU_CMD cycle
    times (+ one plant step, its check granularity) of the last command taken (the plant judges silence on its
    clock: a plant slower than real time sees it sooner in its own time); the pressures decay towards 0 while
    it lasts; valid commands come again (the restarted TCU) and the fallback ends."""
    summary, frames, err, _ = tcu_killed
    cycle = db.get_message_by_name("TCU_CMD").cycle_time / 1000.0
    dt = inspect.signature(plant_for).parameters["dt"].default  # the plant's fixed step: its check granularity
    fallbacks = [float(t) for t in FALLBACK.findall(err)]
    resumed = [float(t) for t in RESUMED.findall(err)]
    assert fallbacks and resumed, err
    # the kill: the fallback with the longest outage until control resumed
    pairs = [(f, next((r for r in resumed if r >= f), None)) for f in fallbacks]
    start, end = max(pairs, key=lambda p: (p[1] if p[1] is not None else float("inf")) - p[0])
    assert end is not None, "control never resumed after the TCU was started again"
    cmd_id = db.get_message_by_name("TCU_CMD").frame_id
    last_cmd = max(t for t, ident, _ in frames if ident == cmd_id and t <= start)
    detection = start - last_cmd
    print(f"fallback {detection * 1000:.1f} ms = {detection / cycle:.2f} cycles after the last command; "
          f"resumed after {end - start:.2f} s; fallback events {summary['command_fallback']['events']}")
    assert 0 < detection <= 3 * cycle + dt + 1e-6, f"{detection / cycle:.2f} cycle times"
    pressure = db.get_message_by_name("PLANT_PRESSURE")
    during = [pressure.decode(data) for t, ident, data in frames if ident == pressure.frame_id and start <= t < end]
    assert len(during) > 5
    for key in ("P_CL", "P_CH"):
        values = [p[key] for p in during]
        assert all(b <= a + 1e-9 for a, b in pairwise(values)), f"{key} rose in the fallback: {values}"
    lsb = pressure.get_signal_by_name("P_CL").scale
    for key in ("P_CL", "P_CH"):  # towards 0 (first-order decay: to under 5 % within 3 time constants, 150 ms)
        if end - start > 0.15:
            assert during[-1][key] <= 0.05 * during[0][key] + lsb, f"{key}: {during[0][key]} -> {during[-1][key]}"
    after = [t for t, ident, _ in frames if ident == cmd_id and t > end]
    assert len(after) > 10, "too few commands after the TCU came back"


# ---- the plant killed under a TCU ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def plant_killed(db, outdir):
    """A real-time creep whose plant is killed (SIGKILL) once the TCU's statuses flow."""
    status_id = db.get_message_by_name("TCU_STATUS").frame_id
    dump = Candump(outdir / "plant_kill.candump.log")
    tcu = start_tcu("--idle-exit", "3")
    plant, _, _ = start_plant(outdir, "plant_kill", "realtime", 600)  # killed below
    try:
        wait_for(lambda: on_bus(dump, status_id) >= 20, STARTUP, "the TCU's statuses")
        plant.send_signal(signal.SIGKILL)
        plant.wait(timeout=30)
        tcu_err = stop(tcu, timeout=120)
    finally:
        for proc in (plant, tcu):
            if proc.poll() is None:
                proc.kill()
        recorded = dump.stop()
    assert tcu.returncode == 0, tcu_err
    return sorted(recorded, key=lambda f: f[0])


def test_plant_kill_tcu_reports_fault(db, plant_killed):
    """On candump's timestamps: after the plant's last frame the TCU keeps sending TCU_STATUS, reports FAULT at the
    latest in its third status (cycle-counted: no uniform pace assumed), and commands no pressure from then on."""
    frames = plant_killed
    status, cmd = db.get_message_by_name("TCU_STATUS"), db.get_message_by_name("TCU_CMD")
    plant_ids = {m.frame_id for m in db.messages if m.senders == ["PLANT"]}
    last_plant = max(t for t, ident, _ in frames if ident in plant_ids)
    states = [(t, status.decode(data)["State"]) for t, ident, data in frames
              if ident == status.frame_id and t > last_plant]
    before = [str(status.decode(data)["State"]) for t, ident, data in frames
              if ident == status.frame_id and t <= last_plant]
    assert before, "no TCU_STATUS before the kill"
    print(f"TCU_STATUS before the kill: {len(before)}, {before.count('FAULT')} of them FAULT (plant frames late)")
    faults = [i for i, (_, s) in enumerate(states) if str(s) == "FAULT"]
    assert faults, f"no FAULT after the plant's last frame: {states[:5]}"
    first = faults[0]
    cycle = status.cycle_time / 1000.0
    print(f"FAULT in status #{first + 1} after the plant's last frame, "
          f"{(states[first][0] - last_plant) / cycle:.2f} TCU_STATUS cycles later")
    assert first < 3 and all(str(s) == "FAULT" for _, s in states[first:])
    commands = [cmd.decode(data) for t, ident, data in frames if ident == cmd.frame_id and t > states[first][0]]
    assert commands and all(c["P_CL_Cmd"] == 0 and c["P_CH_Cmd"] == 0 for c in commands)
