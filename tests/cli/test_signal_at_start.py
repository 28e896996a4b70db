"""Ctrl-C and SIGTERM at any moment of ``dsg-hil run``, ``dsg-hil plant`` and ``ecu-stub``, the first seconds
included (the command's modules loading, the files read, the plant compiled, the bus opened): exit 130 / 143, no
traceback, and the summary asked for, saying how the run ended (issue 20, item 4: a traceback at 0.3 s and 1 s,
no summary at 2.5 s). The moments are found by what the process shows, never by the clock: its handlers in place
(``SigCgt`` in ``/proc/PID/status``, set by ``main`` first thing), a library mapped (``/proc/PID/maps``), a line
it printed. (Before ``main`` runs, the interpreter starting, Python's own handling applies: not tested.)"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from .test_cli_run_ends import DSG_HIL, ECU_STUB, terminal_signals, udp_bus, wait_for

pytestmark = pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux's /proc")

SIGNALS = [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")]


def handles_sigterm(pid: int) -> bool:
    """Whether the process catches SIGTERM: ``main`` installs its handlers first (Python alone does not)."""
    status = Path(f"/proc/{pid}/status").read_text()
    caught = int(next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")), 16)
    return bool(caught >> (signal.SIGTERM - 1) & 1)


def has_mapped(name: str) -> Callable[[int], bool]:
    """Whether the process has a shared library of ``name`` loaded (an import under way or done)."""
    return lambda pid: name in Path(f"/proc/{pid}/maps").read_text()


def wait_until(proc: subprocess.Popen, shows: Callable[[int], bool]) -> None:
    """Poll the process until it shows the moment; fail if it exits first."""
    while not shows(proc.pid):
        if proc.poll() is not None:
            pytest.fail(f"exited ({proc.returncode}) before the moment: {proc.communicate()[1]}")


def start(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen(args, stderr=subprocess.PIPE, text=True, preexec_fn=terminal_signals)  # noqa: PLW1509


def ended(proc: subprocess.Popen, sig: int) -> str:
    proc.send_signal(sig)
    try:
        return proc.communicate(timeout=300)[1]
    finally:
        if proc.poll() is None:
            proc.kill()


def assert_ended_cleanly(proc: subprocess.Popen, err: str, code: int, reason: str) -> None:
    assert proc.returncode == code, err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert err.strip().splitlines()[-1] == f"error: {reason}", err


def assert_summary(path: Path, reason: str, periods: bool) -> dict:
    summary = json.loads(path.read_text())
    assert summary["stop_reason"] == reason and summary["scenario"] and summary["duration_s"] == 1000.0
    if not periods:  # none ran: that of zero periods, all its keys there
        assert summary["sim_time_s"] == 0.0 and summary["frames"]["sent"] == 0 and summary["wall_time_s"] is None
        assert summary["handovers"] == [] and summary["creep_time_s"] == 0.0
    return summary


@pytest.mark.slow
@pytest.mark.parametrize("sig, code, reason", SIGNALS)
def test_run_signalled_as_soon_as_main_runs(tmp_path, sig, code, reason):
    """The first moment main handles signals (it parses the options, imports the command): no period runs,
    the summary of zero periods is written all the same."""
    proc = start([*DSG_HIL, "run", "--duration", "1000", "--summary", str(tmp_path / "s.json")])
    wait_until(proc, handles_sigterm)
    err = ended(proc, sig)
    assert_ended_cleanly(proc, err, code, reason)
    assert_summary(tmp_path / "s.json", reason, periods=False)


@pytest.mark.slow
@pytest.mark.parametrize("library", ["_multiarray_umath", "llvmlite"])  # numpy loading; numba (the plant compiled)
@pytest.mark.parametrize("sig, code, reason", SIGNALS)
def test_run_signalled_while_it_sets_up(tmp_path, sig, code, reason, library):
    """Signals while the plant's modules load or its physics is compiled: held until the run is set up (a
    KeyboardInterrupt inside numba's compiler or an import left a traceback, or exit -2), then the run ends."""
    proc = start([*DSG_HIL, "run", "--duration", "1000", "--summary", str(tmp_path / "s.json")])
    wait_until(proc, has_mapped(library))
    err = ended(proc, sig)
    assert_ended_cleanly(proc, err, code, reason)
    summary = assert_summary(tmp_path / "s.json", reason, periods=True)
    assert summary["sim_time_s"] < 1000.0


def test_run_without_summary_signalled_at_once_writes_nothing(tmp_path):
    proc = subprocess.Popen([*DSG_HIL, "run", "--duration", "1000"], stderr=subprocess.PIPE, text=True,
                            cwd=tmp_path, preexec_fn=terminal_signals)  # noqa: PLW1509
    wait_until(proc, handles_sigterm)
    err = ended(proc, signal.SIGINT)
    assert_ended_cleanly(proc, err, 130, "interrupted")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("sig, code, reason", SIGNALS)
def test_plant_signalled_at_once_and_once_it_said_where(tmp_path, sig, code, reason):
    bus = udp_bus()
    first = start([*DSG_HIL, "plant", *bus, "--duration", "1000", "--summary", str(tmp_path / "a.json")])
    wait_until(first, handles_sigterm)
    err = ended(first, sig)
    assert_ended_cleanly(first, err, code, reason)
    assert_summary(tmp_path / "a.json", reason, periods=False)
    later = start([*DSG_HIL, "plant", *bus, "--duration", "1000", "--summary", str(tmp_path / "b.json")])
    wait_for(later, "plant: ")  # set up: on the bus, stepping in real time
    err = ended(later, sig)
    assert_ended_cleanly(later, err, code, reason)
    assert_summary(tmp_path / "b.json", reason, periods=True)


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_ecu_stub_signalled_as_soon_as_main_runs(sig, code):
    """Its python-can and cantools load after main's handlers: a signal then ends it with its code, no
    traceback (it printed one at Ctrl-C in its first half second)."""
    tcu = start([*ECU_STUB, *udp_bus()])
    wait_until(tcu, handles_sigterm)
    err = ended(tcu, sig)
    assert tcu.returncode == code, err
    assert "Traceback" not in err and "Exception ignored" not in err, err


def test_entry_points_import_nothing_heavy_before_main():
    """What runs before main's handlers (the modules the entry points import) is the standard library and
    dsg_hil.common: python-can, numpy and cantools load after."""
    code = ("import sys, dsg_hil.cli, ecu_stub.cli; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'can', 'cantools', 'numba')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stdout + out.stderr


def test_the_summary_of_zero_periods_has_every_key_of_a_real_one_in_order(tmp_path):
    from dsg_hil.results.outcome import Summary
    from dsg_hil.sim.run import RunConfig, open_run, unstarted_summary

    with open_run(RunConfig(duration=0.05)) as run:
        real = run.run().as_json()
    none = unstarted_summary("interrupted", tmp_path / "s.json", "creep", "lockstep", "virtual", 1000.0).as_json()
    assert list(none) == list(real)
    assert json.loads((tmp_path / "s.json").read_text()) == none
    assert Summary.from_json(none).stop_reason == "interrupted"
