"""How a run ends, through the command line: the summary is written on Ctrl-C (exit 130), SIGTERM (exit 143) and
when the TCU dies (exit 1); unwritable --log/--summary paths fail before the run. Plant and ecu-stub as two
processes over python-can's udp_multicast (no kernel CAN needed): lockstep gives the log of the in-process run."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import can
import pytest

from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.bus import bus_args, fresh_udp_group
from ecu_stub.runner import TCU_USES

DSG_HIL = [sys.executable, "-m", "dsg_hil"]
ECU_STUB = [sys.executable, "-m", "ecu_stub"]
REPLY_TIMEOUT = "10"  # [s] a live TCU on a loaded machine was once starved 1 s (a run ended as peer_lost at t=5.4 s)
# [s] ecu-stub ends once the plant is this long silent: well above a loaded machine's pauses (at 2 s, a plant starved
# mid-run under pytest -n 2 beside a sweep lost its TCU: 'TCU silent for 5 s at lock-step tick 59')
TCU_IDLE_EXIT = "10"


def terminal_signals() -> None:
    """A child started as a user's terminal starts it: Ctrl-C's signal at its default disposition (a test run
    started in the background by a non-interactive shell inherits SIGINT ignored, and so would its children)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_run(tmp_path: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([*DSG_HIL, "run", "--interface", "virtual", "--duration", "1000", "--summary",
                             str(tmp_path / "s.json"), "--log", str(tmp_path / "r.log"), *extra],
                            stderr=subprocess.PIPE, text=True, preexec_fn=terminal_signals)  # noqa: PLW1509


def wait_for(proc: subprocess.Popen, text: str, timeout: float = 120.0) -> list[str]:
    """stderr lines up to the first containing ``text``."""
    lines, deadline = [], time.monotonic() + timeout
    assert proc.stderr is not None  # started with stderr=PIPE
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        if not line:
            break
        lines.append(line)
        if text in line:
            return lines
    proc.kill()
    pytest.fail(f"never saw {text!r}: {''.join(lines)}")


@pytest.mark.slow
@pytest.mark.parametrize("sig, code, reason", [(signal.SIGINT, 130, "interrupted"),
                                               (signal.SIGTERM, 143, "terminated")])
def test_signal_ends_the_run_with_summary_and_log(tmp_path, sig, code, reason):
    proc = start_run(tmp_path)
    line = wait_for(proc, "t=   10.0/1000 s")[-1]  # a progress line: the run is under way
    assert re.search(r"  \d+\.\dx real time, ETA \d+ s$", line), line  # its pace and the wall time left
    proc.send_signal(sig)
    err = proc.communicate(timeout=60)[1]
    assert proc.returncode == code, err
    assert err.strip().splitlines()[-1] == f"error: {reason}"
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["stop_reason"] == reason and 10.0 <= summary["sim_time_s"] < 1000.0
    assert summary["frames"]["by_message"]["SIM_SYNC"]["sent"] >= 1000
    lines = (tmp_path / "r.log").read_text().splitlines()
    assert len(lines) > 5000 and all(line.split()[2].count("#") == 1 for line in lines)  # closed cleanly


@pytest.mark.parametrize("option, path, message", [
    ("--summary", ".", "is a directory"),
    ("--log", "afile/run.log", "afile is not a writable directory"),
    ("--summary", "afile/sub/s.json", "afile is not a writable directory"),
])
def test_unwritable_outputs_fail_before_the_run(tmp_path, option, path, message):
    (tmp_path / "afile").write_text("a file, not a directory")
    proc = subprocess.run([*DSG_HIL, "run", "--interface", "virtual", "--duration", "1000", option, path],
                          capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert proc.returncode == 2  # bad input
    assert proc.stderr.strip().splitlines() == [f"error: {option} {path}: {message}"]  # before the run starts


def udp_bus() -> list[str]:
    """Bus options of a udp_multicast group and port of this test's own (:func:`fresh_udp_group`). The port matters:
    python-can binds it on every address and Linux hands a datagram to every socket on its port that joined any
    group, so tests sharing python-can's default port heard each other's frames when run concurrently."""
    config = {"interface": "udp_multicast", **fresh_udp_group()}
    try:
        a = can.Bus(**config)
        b = can.Bus(**config)
    except (OSError, can.CanError) as exc:
        pytest.skip(f"this machine cannot do UDP multicast: {exc}")
    try:
        a.send(can.Message(arbitration_id=0x7FF, data=bytes(8), is_extended_id=False))
        if b.recv(2.0) is None:
            pytest.skip("this machine cannot do UDP multicast: nothing came back on loopback")
    finally:
        a.shutdown()
        b.shutdown()
    return bus_args(config)


def log_frames(path: Path) -> list[tuple[str, str]]:
    """(timestamp, id#data) of a candump -L log, without the channel name."""
    return [(line.split()[0], line.split()[2]) for line in path.read_text().splitlines()]


UDP_DURATION = "20"


@pytest.fixture(scope="module")
def reference_log(tmp_path_factory) -> Path:
    """The plant log of the in-process lockstep run on virtual."""
    path = tmp_path_factory.mktemp("ref") / "ref.log"
    ref = subprocess.run([*DSG_HIL, "run", "--interface", "virtual", "--duration", UDP_DURATION, "--log", str(path)],
                         capture_output=True, text=True, timeout=600)
    assert ref.returncode == 0, ref.stderr
    return path


def udp_lockstep(tmp_path: Path, during=None) -> tuple[dict, str]:
    """ecu-stub and dsg-hil plant (lockstep) as processes on a multicast group of their own; ``during(tcu,
    plant)`` runs while both are up. Returns the plant's summary and the TCU's stderr."""
    bus = udp_bus()
    tcu = subprocess.Popen([*ECU_STUB, *bus, "--idle-exit", TCU_IDLE_EXIT, "--log", str(tmp_path / "tcu.log")],
                           stderr=subprocess.PIPE, text=True)
    assert tcu.stderr is not None  # stderr=PIPE
    try:
        assert "listening on udp_multicast" in tcu.stderr.readline()
        plant = subprocess.Popen([*DSG_HIL, "plant", *bus, "--mode", "lockstep", "--duration", UDP_DURATION,
                                  "--reply-timeout", REPLY_TIMEOUT, "--log", str(tmp_path / "plant.log"),
                                  "--summary", str(tmp_path / "s.json")],
                                 stderr=subprocess.PIPE, text=True)
        if during is not None:
            during(tcu, plant)
        plant_err = plant.communicate(timeout=600)[1]
        tcu_err = tcu.communicate(timeout=60)[1]
    finally:
        for proc in (tcu, plant):
            if proc.poll() is None:
                proc.kill()
    assert plant.returncode == 0, plant_err
    assert tcu.returncode == 0 and "ecu-stub: sent" in tcu_err, tcu_err
    return json.loads((tmp_path / "s.json").read_text()), tcu_err


@pytest.mark.slow
def test_lockstep_across_two_processes_over_udp_multicast(tmp_path, reference_log):
    """ecu-stub and dsg-hil plant as separate processes: the plant's log is that of the in-process run."""
    summary, _ = udp_lockstep(tmp_path)
    assert summary["frames"]["rejected"] == 0 and summary["frames"]["unanswered_ticks"] == 0
    assert log_frames(tmp_path / "plant.log") == log_frames(reference_log)
    assert_records_agree(tmp_path)


def assert_records_agree(tmp_path: Path) -> None:
    """The TCU's record (``ecu-stub --log``) is the other half of the plant's log: the TCU took every frame the
    plant sent on the IDs it reads, and sent every frame the plant took, each with the same stamp (its tick's
    time), nothing else (neither re-sends nor the presence handshake). Compared sorted: each side records in
    its own arrival order."""
    db = load_dbc()
    ids = {f"{db.get_message_by_name(name).frame_id:03X}" for name in TCU_USES}
    tcu = log_frames(tmp_path / "tcu.log")
    plant = [(t, frame) for t, frame in log_frames(tmp_path / "plant.log") if frame.split("#")[0] in ids]
    assert len(tcu) > 1000 and sorted(tcu) == sorted(plant)


@pytest.mark.slow
def test_a_stalled_tcu_costs_retries_not_the_log(tmp_path, reference_log):
    """The TCU process stopped for a second mid-run (a starved process): the plant re-sends the tick, the TCU,
    woken, answers the tick and its repeats; the plant counts the repeats as duplicates, and logs the frames of
    a clean run."""
    def stall(tcu, plant):
        wait_for(plant, "t=   10.0/20 s")
        tcu.send_signal(signal.SIGSTOP)
        time.sleep(1.0)
        tcu.send_signal(signal.SIGCONT)

    summary, tcu_err = udp_lockstep(tmp_path, during=stall)
    frames = summary["frames"]
    assert frames["by_message"]["SIM_SYNC"]["retries"] >= 2 and frames["by_message"]["TCU_CMD"]["duplicates"] >= 1
    assert frames["rejected"] == 0 and frames["unanswered_ticks"] == 0 and frames["lost"] == 0
    assert "answers re-sent" in tcu_err and "(0 lock-step answers re-sent)" not in tcu_err
    assert log_frames(tmp_path / "plant.log") == log_frames(reference_log)
    assert_records_agree(tmp_path)


@pytest.mark.slow
def test_a_known_fault_on_the_tcus_answers_is_no_lost_peer(tmp_path):
    """The README's fault across processes: ``run -i udp_multicast`` passes ``drop:TCU_CMD`` to the ecu-stub it
    starts, which drops its answers (and their repeats) to the ten ticks of the window. The run finishes (exit 0):
    ten ticks unanswered in one episode, one warning, one fallback, the fault counted by ecu-stub; and the log is
    the in-process run's with the same fault, bit for bit. (Before: each tick cost the whole re-send back-off and
    the silence summed over them ended the run as peer lost.)"""
    fault = ["--duration", "3", "--fault", "drop:TCU_CMD@2-2.1"]
    udp = subprocess.run([*DSG_HIL, "run", "-i", "udp_multicast", *fault, "--log", str(tmp_path / "udp.log"),
                          "--summary", str(tmp_path / "s.json")], capture_output=True, text=True, timeout=600)
    assert udp.returncode == 0, udp.stderr
    assert "ecu-stub: faults injected (frames hit): drop:TCU_CMD@2-2.1 " in udp.stderr
    assert udp.stderr.count("unanswered after its re-sends (an injected fault)") == 1
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["stop_reason"] == "end_of_record" and summary["faults"]["in_tcu_process"] == ["drop:TCU_CMD@2-2.1"]
    assert summary["frames"]["unanswered_ticks"] == 10 and summary["frames"]["unanswered_episodes"] == 1
    assert summary["command_fallback"]["events"] == 1
    local = subprocess.run([*DSG_HIL, "run", *fault, "--log", str(tmp_path / "local.log")], capture_output=True,
                           text=True, timeout=600)
    assert local.returncode == 0, local.stderr
    assert (tmp_path / "udp.log").read_bytes() == (tmp_path / "local.log").read_bytes()


@pytest.mark.slow
def test_dead_tcu_ends_a_lockstep_run_as_peer_lost(tmp_path):
    """The TCU process killed mid-run: the plant says so in one line, exits 1 and writes the summary so far."""
    bus = udp_bus()
    tcu = subprocess.Popen([*ECU_STUB, *bus], stderr=subprocess.PIPE, text=True)
    try:
        assert "listening on udp_multicast" in tcu.stderr.readline()
        plant = subprocess.Popen([*DSG_HIL, "plant", *bus, "--mode", "lockstep", "--duration", "1000",
                                  "--reply-timeout", REPLY_TIMEOUT, "--summary", str(tmp_path / "s.json")],
                                 stderr=subprocess.PIPE, text=True)
        wait_for(plant, "t=   10.0/1000 s")
    finally:
        tcu.kill()
        tcu.wait()
    err = plant.communicate(timeout=120)[1]
    assert plant.returncode == 1, err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"error: TCU silent for {REPLY_TIMEOUT} s at lock-step tick ") and "peer lost" in last
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["stop_reason"] == "peer_lost" and 10.0 <= summary["sim_time_s"] < 1000.0
    assert summary["frames"]["by_message"]["SIM_SYNC"]["retries"] > 0




@pytest.mark.slow
def test_no_tcu_at_all_ends_with_a_summary(tmp_path):
    """No TCU answers the presence probe: one line, exit 1, and the summary all the same (stop reason no_peer)."""
    bus = udp_bus()
    plant = subprocess.run([*DSG_HIL, "plant", *bus, "--mode", "lockstep", "--duration", "5", "--startup-timeout",
                            "0.5", "--summary", str(tmp_path / "s.json")], capture_output=True, text=True, timeout=120)
    assert plant.returncode == 1, plant.stderr
    assert plant.stderr.strip().splitlines()[-1].startswith("error: no TCU answered the lock-step presence probe")
    assert plant.stderr.count("lock-step: waiting for a TCU to answer") == 1  # said at once, not after 60 s
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["stop_reason"] == "no_peer" and summary["frames"]["probes"] >= 1
    assert summary["frames"]["by_message"]["PLANT_ENGINE"]["sent"] == 0  # nothing but probes went out

@pytest.mark.parametrize("sig, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_ecu_stub_ends_on_a_signal_with_the_same_codes_as_dsg_hil(sig, status):
    tcu = subprocess.Popen([*ECU_STUB, *udp_bus()], stderr=subprocess.PIPE, text=True,
                           preexec_fn=terminal_signals)  # noqa: PLW1509
    try:
        assert "listening on udp_multicast" in tcu.stderr.readline()
        tcu.send_signal(sig)
        err = tcu.communicate(timeout=60)[1]
    finally:
        if tcu.poll() is None:
            tcu.kill()
    assert tcu.returncode == status and "ecu-stub: sent 0 frames" in err, err


@pytest.mark.slow
def test_a_real_time_plant_that_never_hears_a_tcu_fails(tmp_path):
    """Real time with nobody on the bus (a mistyped channel): exit 1 and a line saying so, not a clean-looking
    run; the summary is written, stop reason no_peer (issue 20, item 5: it exited 0)."""
    plant = subprocess.run([*DSG_HIL, "plant", *udp_bus(), "--duration", "1", "--summary", str(tmp_path / "s.json")],
                           capture_output=True, text=True, timeout=120)
    assert plant.returncode == 1, plant.stderr
    last = plant.stderr.strip().splitlines()[-1]
    assert last.startswith("error: real time: not one frame from a TCU in the 1 s run") and "udp_multicast" in last
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["stop_reason"] == "no_peer" and summary["frames"]["received"] == 0


FAULT = ["--duration", "1", "--fault", "drop:TCU_CMD@0.2-0.3"]  # ten ticks in a row unanswered, one fallback


@pytest.mark.slow
def test_one_warning_per_run_of_unanswered_ticks_and_quiet_prints_none():
    loud = subprocess.run([*DSG_HIL, "run", *FAULT], capture_output=True, text=True, timeout=300)
    assert loud.returncode == 0, loud.stderr
    warnings = [line for line in loud.stderr.splitlines() if line.startswith("WARNING")]
    assert sum("unanswered" in line for line in warnings) == 1, loud.stderr  # not one per tick
    assert "unanswered ticks 10 (1 run of them)" in loud.stderr
    quiet = subprocess.run([*DSG_HIL, "run", *FAULT, "--quiet"], capture_output=True, text=True, timeout=300)
    assert quiet.returncode == 0 and quiet.stderr == ""


def test_a_controller_process_that_exits_ends_the_wait_at_once(tmp_path):
    """The fixture's command-line controller exits (status 3) after a second, before answering: the run fails
    then, with its status and output, not after the 60-s presence-probe timeout (issue 20, item 6)."""
    from dsg_hil.sim.run import PeerTimeout
    from dsg_hil.testing import run_plant

    script = "import sys, time; time.sleep(1.0); sys.stderr.write('controller: cannot open the bus\\n'); sys.exit(3)"
    with pytest.raises(PeerTimeout) as info:
        run_plant([sys.executable, "-c", script], duration=1.0, out_dir=tmp_path)
    message = str(info.value)
    assert message.startswith("the TCU process exited before it answered the presence probe")
    assert "exited with status 3" in message and "controller: cannot open the bus" in message
