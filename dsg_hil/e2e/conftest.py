"""End-to-end tests on a real SocketCAN vcan0, with separate processes and can-utils.

They need vcan0 and can-utils. Where those are missing they are skipped, unless DSG_HIL_REQUIRE_VCAN is set
(``dsg-hil vcan`` and CI set it): then they fail with the reason. Run them anywhere with ``dsg-hil vcan``."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.codec import DEFAULT_DBC
from dsg_hil.vcan import ENV_DURATION, ENV_OUTDIR, ENV_REQUIRE, vcan_present

DBC = Path(str(DEFAULT_DBC))  # the DBC inside the installed package, for 'cantools decode'


def pytest_configure(config):
    config.addinivalue_line("markers", "vcan: end-to-end on a real SocketCAN vcan0 (run with 'dsg-hil vcan')")


def pytest_collection_modifyitems(items):
    for item in items:
        if Path(str(item.fspath)).parent == Path(__file__).parent:
            item.add_marker(pytest.mark.vcan)


@pytest.fixture(scope="session", autouse=True)
def vcan_ready():
    missing = [] if vcan_present() else ["vcan0 (no /sys/class/net/vcan0)"]
    missing += [tool for tool in ("candump", "canplayer") if shutil.which(tool) is None]
    if missing:
        reason = f"needs {', '.join(missing)}: run 'dsg-hil vcan' (native or VM), see README"
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
    assert found, f"console script {name} is not installed (pip install -e .)"
    return found


class Candump:
    """``candump -L vcan0`` writing to a file while the test runs."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.file = path.open("w")
        self.proc = subprocess.Popen(["candump", "-L", "vcan0"], stdout=self.file, stderr=subprocess.PIPE)
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


def parse_candump(path: Path) -> list[tuple[float, int, bytes]]:
    frames = []
    for line in path.read_text().splitlines():
        parts = line.split()
        if len(parts) < 3 or "#" not in parts[2]:
            continue
        ident, data = parts[2].split("#", 1)
        frames.append((float(parts[0].strip("()")), int(ident, 16), bytes.fromhex(data)))
    return frames
