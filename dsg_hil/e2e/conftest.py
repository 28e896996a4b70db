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
import threading
import time
from collections import defaultdict
from collections.abc import Iterable
from pathlib import Path

import pytest

from ..common.build import EXPECT_ENV, build
from ..protocol import load_dbc
from ..protocol.codec import DEFAULT_DBC
from ..protocol.diag import diag_ids, load_description
from .vcan import ENV_DURATION, ENV_OUTDIR, ENV_REQUIRE, vcan_present

BUS = ["--interface", "socketcan", "--channel", "vcan0"]
DBC = Path(str(DEFAULT_DBC))  # the DBC inside the installed package, for 'cantools decode'
RCVBUF = 8 * 1024 * 1024  # candump's socket receive buffer [bytes]
TCU_IDLE_EXIT = "10"  # [s] ecu-stub ends once the plant is this long silent: well above a loaded machine's pauses
UDS_TIMEOUT = 60.0  # [s] per UDS request: a starved VM answers late, never wrongly
UDS_PATIENCE = 120.0  # [s] the TCU's wait for the tester after the plant has ended (--idle-exit; SIGTERM ends it)
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
    return float(os.environ.get(ENV_DURATION, "5"))


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
    """(time, ID, data) of each frame of a ``candump -L`` log: "(t) vcan0 ID#DATA", a CAN FD frame "ID##<flags>DATA"
    (its flags nibble dropped)."""
    frames = []
    for line in path.read_text().splitlines():
        parts = line.split()
        if len(parts) < 3 or "#" not in parts[2]:
            continue
        ident, data = parts[2].split("#", 1)
        if data.startswith("#"):  # CAN FD: one hex digit of flags (BRS, ESI) before the data
            data = data[2:]
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


class UdsTester:
    """A UDS tester in a thread of the test process, as a HIL test specification has one: udsoncan over can-isotp
    (extra ``diag``) on its own socket on vcan0, talking to the ecu-stub process while the creep runs. It reads the
    predicted plate temperatures and the state (ReadDataByIdentifier) until the plant has ended, then the DTCs
    (ReadDTCInformation with their freeze frames) until the plant's silence has confirmed the TCU's timeout DTCs,
    and lets the TCU go. ``readings``: (asked, answered [s, candump's clock], {DID name: fields}); ``dtcs``: the
    last DTC report; ``error``: what failed."""

    def __init__(self, db, bus: dict | None = None) -> None:
        self.bus = bus or {"interface": "socketcan", "channel": "vcan0"}
        self.ids = diag_ids(db)
        self.description = load_description()
        self.plant_ended = threading.Event()
        self.readings: list[tuple[float, float, dict]] = []
        self.dtcs: list = []
        self.not_yet = 0  # readings answered ConditionsNotCorrect: no plant frame heard yet
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._talk, daemon=True)

    def _talk(self) -> None:
        import can  # noqa: PLC0415
        from udsoncan import Response  # noqa: PLC0415 - extra diag
        from udsoncan.exceptions import NegativeResponseException  # noqa: PLC0415

        from ..protocol.diag_client import read_dids, read_dtcs, uds_client  # noqa: PLC0415
        try:
            with can.Bus(**self.bus) as bus, \
                    uds_client(bus, self.description, *self.ids, timeout=UDS_TIMEOUT) as client:
                while not self.plant_ended.is_set():
                    asked = time.time()  # candump's clock
                    try:
                        values = read_dids(client, self.description, (0x0101, 0x0102))
                    except NegativeResponseException as exc:  # before the TCU has heard the plant
                        if exc.response.code != Response.Code.ConditionsNotCorrect:
                            raise
                        self.not_yet += 1
                    else:
                        self.readings.append((asked, time.time(), values))
                    self.plant_ended.wait(0.2)
                deadline = time.monotonic() + UDS_PATIENCE / 2  # the TCU waits UDS_PATIENCE
                while time.monotonic() < deadline:
                    self.dtcs = read_dtcs(client, self.description, mask=0x08)  # confirmed
                    if len({d.name for d in self.dtcs if d.name.endswith("_timeout")}) >= 5:
                        break
                    time.sleep(0.5)
        except BaseException as exc:  # noqa: BLE001 - reported by the test, never lost in the thread
            self.error = exc


def run_pair(outdir, name, mode, duration, extra=(), tester: UdsTester | None = None):
    """Start candump and ecu-stub, run the plant to the end, stop both; returns (summary, frames, log path).

    ``frames`` are candump's, in timestamp order (its file order is delivery order, which on several CPUs can put
    a reply before the frame it answers); in lockstep, from the start of the run (see ``lockstep_run``). The DBC's
    messages only: a ``tester`` (:class:`UdsTester`, started once the TCU listens) talks on the diagnostic IDs."""
    dump = Candump(outdir / f"{name}.candump.log")
    idle_exit = str(UDS_PATIENCE) if tester else TCU_IDLE_EXIT
    tcu = subprocess.Popen([console("ecu-stub"), *BUS, "--idle-exit", idle_exit], stderr=subprocess.PIPE, text=True)
    summary = outdir / f"{name}.summary.json"
    try:
        if tester:
            assert tcu.stderr is not None and "listening on socketcan:vcan0" in tcu.stderr.readline()
            tester.thread.start()
        plant = subprocess.Popen([console("dsg-hil"), "plant", *BUS, "--mode", mode, "--duration", str(duration),
                                  "--reply-timeout", "60", "--summary", str(summary), *extra],
                                 stderr=subprocess.PIPE, text=True)
        plant_err = finish_while_progressing(plant, dump.path)
        assert plant.returncode == 0, plant_err
        if tester:  # the tester reads the DTCs the plant's silence sets, then the TCU is stopped as a bench does
            tester.plant_ended.set()
            tester.thread.join(timeout=UDS_PATIENCE + 2 * UDS_TIMEOUT)
            tcu.send_signal(signal.SIGTERM)
        tcu_err = tcu.communicate(timeout=120)[1]
        assert tcu.returncode == (143 if tester else 0), tcu_err  # SIGTERM: counts reported, exit 143
    finally:
        if tcu.poll() is None:
            tcu.kill()
        frames = dump.stop()
        if tester:
            tester.plant_ended.set()
    (outdir / f"{name}.plant.stderr").write_text(plant_err)
    messages = {m.frame_id for m in load_dbc().messages}
    frames = sorted((f for f in frames if f[1] in messages), key=lambda f: f[0])
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
def realtime(outdir, duration, db):
    """The real-time pair, with a UDS tester talking to the TCU all along (:class:`UdsTester`); returns
    (summary, frames, log path, tester)."""
    tester = UdsTester(db)
    return (*run_pair(outdir, "realtime", "realtime", min(duration, 6.0), tester=tester), tester)
