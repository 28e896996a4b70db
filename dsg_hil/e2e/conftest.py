"""End-to-end tests on a real SocketCAN vcan0, with separate processes and can-utils.

They need vcan0 and can-utils. Where those are missing they are skipped, unless DSG_HIL_REQUIRE_VCAN is set
(``dsg-hil vcan`` and CI set it): then they fail with the reason. Run them anywhere with ``dsg-hil vcan``."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections import defaultdict
from collections.abc import Iterable
from pathlib import Path

import pytest

from ..common.build import EXPECT_ENV, build
from ..protocol import load_dbc
from ..protocol.codec import DEFAULT_DBC
from .vcan import ENV_DURATION, ENV_OUTDIR, ENV_REQUIRE, vcan_present

BUS = ["--interface", "socketcan", "--channel", "vcan0"]
DBC = Path(str(DEFAULT_DBC))  # the DBC inside the installed package, for 'cantools decode'
RCVBUF = 8 * 1024 * 1024  # candump's socket receive buffer [bytes]
TCU_IDLE_EXIT = "10"  # [s] ecu-stub ends once the plant is this long silent: well above a loaded machine's pauses
STARTUP = 1800.0  # [s] for the first frames of a run (imports and compiled code loaded under emulation)
STALL = 300.0  # [s] a process whose record does not grow for this long has stalled (emulation under load: slow)


def pytest_configure(config):
    config.addinivalue_line("markers", "vcan: end-to-end on a real SocketCAN vcan0 (run with 'dsg-hil vcan')")


def pytest_report_header(config):
    """Which build the end-to-end tests run (the processes they start import the same package)."""
    return f"dsg-hil build: {build()} ({Path(str(DEFAULT_DBC)).parents[1]})"


def pytest_collection_modifyitems(items):
    for item in items:
        if Path(str(item.fspath)).parent == Path(__file__).parent:
            item.add_marker(pytest.mark.vcan)


@pytest.fixture(scope="session", autouse=True)
def vcan_ready():
    missing = [] if vcan_present() else ["vcan0 (no /sys/class/net/vcan0)"]
    missing += [tool for tool in ("candump", "canplayer") if shutil.which(tool) is None]
    if os.environ.get(EXPECT_ENV, "") not in ("", "0") and build() != "compiled":
        pytest.fail(f"{EXPECT_ENV} is set but the build loaded is {build()}: the tests would not test the "
                    "compiled build", pytrace=False)
    if missing:
        reason = f"needs {', '.join(missing)}: run 'dsg-hil vcan' (native or VM), see docs/how-to/run-tests.md"
        if os.environ.get(ENV_REQUIRE):
            pytest.fail(f"{ENV_REQUIRE} is set but this machine lacks {reason}", pytrace=False)
        pytest.skip(reason)


@pytest.fixture(scope="session")
def duration() -> float:
    return float(os.environ.get(ENV_DURATION, "10"))


@pytest.fixture(scope="session")
def outdir(tmp_path_factory) -> Path:
    path = Path(os.environ.get(ENV_OUTDIR) or tmp_path_factory.mktemp("vcan"))
    path.mkdir(parents=True, exist_ok=True)
    return path


@pytest.fixture(scope="session")
def db():
    return load_dbc()


def console(name: str) -> str:
    """A console script of this environment (next to the interpreter), as a user would start it."""
    path = Path(sys.executable).parent / name
    found = str(path) if path.exists() else shutil.which(name)
    assert found, f"console script {name} is not installed (pip install .)"
    return found


class Candump:
    """``candump -L vcan0`` writing to a file while the test runs; ``ids``: only these (kernel filters)."""

    def __init__(self, path: Path, ids: Iterable[int] | None = None) -> None:
        self.path = path
        self.file = path.open("w")
        channel = "vcan0" if ids is None else "vcan0," + ",".join(f"{ident:03X}:7FF" for ident in ids)
        # a receive buffer for ~8000 frames: a starved candump (emulation, a busy machine) would otherwise drop
        # frames from the recording when a sender catches up in a burst (canplayer does); root may force it
        self.proc = subprocess.Popen(["candump", "-L", "-r", str(RCVBUF), channel], stdout=self.file,
                                     stderr=subprocess.PIPE)
        time.sleep(0.3)

    def stop(self) -> list[tuple[float, int, bytes]]:
        time.sleep(0.3)
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self.file.close()
        return parse_candump(self.path)


def sent_by(db, node: str) -> set[int]:
    """The frame IDs of the DBC messages ``node`` (PLANT or TCU) sends."""
    return {m.frame_id for m in db.messages if m.senders == [node]}


def parse_candump(path: Path) -> list[tuple[float, int, bytes]]:
    frames = []
    for line in path.read_text().splitlines():
        parts = line.split()
        if len(parts) < 3 or "#" not in parts[2]:
            continue
        ident, data = parts[2].split("#", 1)
        frames.append((float(parts[0].strip("()")), int(ident, 16), bytes.fromhex(data)))
    return frames


def finish_while_progressing(proc, record, stall: float = STALL, startup: float = STARTUP) -> str:
    """Wait for ``proc`` to end for as long as it makes progress (its ``record`` file grows: a loaded machine may
    take minutes to finish a creep, and that is no failure). A record still empty after ``startup`` s, or not
    grown for ``stall`` s since, means a process that never started or has stalled: it is killed and the test
    fails saying so. Orchestration only: no figure is judged on this wait."""
    size, last_change = 0, time.monotonic()
    try:
        while True:
            try:
                return proc.communicate(timeout=5.0)[1] or ""
            except subprocess.TimeoutExpired:
                now_size = record.stat().st_size if record.exists() else 0
                if now_size != size:
                    size, last_change = now_size, time.monotonic()
                idle = time.monotonic() - last_change
                assert size or idle < startup, f"{record.name} still empty after {startup:g} s: never started"
                assert not size or idle < stall, f"{record.name} has not grown for {stall:g} s: stalled"
    finally:
        if proc.poll() is None:
            proc.kill()


def run_pair(outdir, name, mode, duration, extra=()):
    """Start candump and ecu-stub, run the plant to the end, stop both; returns (summary, frames, log path).

    ``frames`` are candump's, in timestamp order (its file order is delivery order, which on several CPUs can put
    a reply before the frame it answers); in lockstep, from the start of the run (see ``lockstep_run``)."""
    dump = Candump(outdir / f"{name}.candump.log")
    tcu = subprocess.Popen([console("ecu-stub"), *BUS, "--idle-exit", TCU_IDLE_EXIT], stderr=subprocess.PIPE, text=True)
    summary = outdir / f"{name}.summary.json"
    try:
        plant = subprocess.Popen([console("dsg-hil"), "plant", *BUS, "--mode", mode, "--duration", str(duration),
                                  "--reply-timeout", "60", "--summary", str(summary), *extra],
                                 stderr=subprocess.PIPE, text=True)
        plant_err = finish_while_progressing(plant, dump.path)
        assert plant.returncode == 0, plant_err
        tcu_err = tcu.communicate(timeout=120)[1]
        assert tcu.returncode == 0, tcu_err
    finally:
        if tcu.poll() is None:
            tcu.kill()
        frames = dump.stop()
    (outdir / f"{name}.plant.stderr").write_text(plant_err)
    frames = sorted(frames, key=lambda f: f[0])
    return json.loads(summary.read_text()), lockstep_run(frames) if mode == "lockstep" else frames, dump.path


def lockstep_run(frames):
    """The frames of the run proper: a lockstep plant first probes for the TCU (SIM_SYNC Tick 0xFFFFFFFF,
    answered with SyncEcho 255; documented in the DBC) and sends its first data frame only when answered. So the
    run starts at the first PLANT_ENGINE frame; the probes and the probe answer (repeated identically when the
    TCU heard several probes) are left out."""
    start = next(t for t, ident, _ in frames if ident == 0x100)
    probe_answer = next((data for t, ident, data in frames if ident == 0x200 and t <= start), None)
    tick255 = next((t for t, ident, data in frames if ident == 0x7F0 and data[:4] == bytes((255, 0, 0, 0))),
                   float("inf"))
    return [(t, ident, data) for t, ident, data in frames if t >= start
            and not (ident == 0x7F0 and data[:4] == b"\xff" * 4)
            and not (ident == 0x200 and data == probe_answer and t < tick255)]


def first_transmissions(frames):
    """Without lockstep retransmissions: a frame byte-identical to the previous one of its ID is a re-send (a
    retry after a late answer), counted by the plant and the TCU, never logged by the plant."""
    last, kept = {}, []
    for t, ident, data in frames:
        if last.get(ident) != data:
            kept.append((t, ident, data))
        last[ident] = data
    return kept


def by_id(frames):
    groups = defaultdict(list)
    for t, ident, data in frames:
        groups[ident].append((t, data))
    return groups


def frames_over_cycle(times: list[float], cycle: float) -> float:
    """How many frames ``times`` [s] hold beyond one per ``cycle`` [s] (and the one that opens the count), counted
    from the frame of the first half that was sent least late. A sender on an absolute-deadline grid never sends
    early, but a frame can leave late (the first one off the grid by design, any one after a stall between its
    computing and its sending); counted from a late frame the span is short by that lateness, so the count starts
    where the excess is smallest. A sender that sends too often shows an excess that grows with the run."""
    n, end = len(times), times[-1]
    return min((n - i) - ((end - times[i]) / cycle + 1.0) for i in range(max(1, n // 2)))


def assert_counters_increment(db, frames):
    for ident, items in by_id(frames).items():
        m = db.get_message_by_frame_id(ident)
        counters = [m.decode(data, decode_choices=False)["Counter"] for _, data in items]
        steps = {(b - a) % 16 for a, b in zip(counters, counters[1:])}
        assert steps == {1}, f"{m.name}: counter steps {steps}"


@pytest.fixture(scope="session")
def lockstep(outdir, duration):
    return run_pair(outdir, "lockstep", "lockstep", duration, extra=("--log", str(outdir / "lockstep.plant.log")))


@pytest.fixture(scope="session")
def realtime(outdir, duration):
    return run_pair(outdir, "realtime", "realtime", min(duration, 6.0))
