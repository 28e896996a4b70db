"""``ecu-stub --quiet``, as ``dsg-hil run -q``: errors only while it serves (no 'listening' line, no warnings),
the frame counts at the end, which count what the warnings said (issue 20, item 6)."""

from __future__ import annotations

import json
import re
import subprocess

import pytest

from ecu_stub.cli import _parse_args
from tests.cli.test_cli_run_ends import DSG_HIL, ECU_STUB, REPLY_TIMEOUT, TCU_IDLE_EXIT, udp_bus

FAULT = "corrupt_crc:PLANT_ENGINE@0.5-0.6"  # plant frames the TCU rejects: a warning each, counted as crc


def serve(bus: list[str], tmp_path, *extra: str) -> tuple[str, int]:
    """ecu-stub's stderr for a 1-s lockstep run of the plant with FAULT (the plant waits for it to answer), and how
    many frames the plant corrupted."""
    tcu = subprocess.Popen([*ECU_STUB, *bus, "--idle-exit", TCU_IDLE_EXIT, *extra], stderr=subprocess.PIPE, text=True)
    summary = tmp_path / f"plant{len(extra)}.json"
    try:
        plant = subprocess.run([*DSG_HIL, "plant", *bus, "--mode", "lockstep", "--duration", "1", "--fault", FAULT,
                                "--reply-timeout", REPLY_TIMEOUT, "-q", "--summary", str(summary)], capture_output=True,
                               text=True, timeout=600)
        err = tcu.communicate(timeout=120)[1]
    finally:
        if tcu.poll() is None:
            tcu.kill()
    assert plant.returncode == 0, plant.stderr
    assert tcu.returncode == 0, err
    return err, sum(json.loads(summary.read_text(encoding="utf-8"))["faults"]["injected"].values())


def rejected_by_crc(err: str) -> int:
    match = re.search(r"^ecu-stub: sent \d+ frames .*rejected (\d+) \(crc \1\)", err, re.MULTILINE)
    assert match, err
    return int(match.group(1))


def counted(err: str, corrupted: int) -> bool:
    """The TCU's crc count is the plant's corrupted frames, and at most as many more as frames came again (a
    lock-step tick the TCU answered late is sent again, its corrupted frames too: how many, the machine's load
    decides)."""
    duplicates = re.search(r"duplicates (\d+)", err)
    assert duplicates, err
    return corrupted <= rejected_by_crc(err) <= corrupted + int(duplicates.group(1))


@pytest.mark.slow
def test_quiet_prints_the_counts_alone(tmp_path):
    bus = udp_bus()
    loud, corrupted = serve(bus, tmp_path)
    assert "ecu-stub: listening on udp_multicast" in loud and "WARNING" in loud and corrupted > 0
    assert counted(loud, corrupted)
    quiet, corrupted = serve(bus, tmp_path, "--quiet")
    lines = quiet.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ecu-stub: sent"), quiet  # no injector on the TCU's side
    assert counted(quiet, corrupted)  # the counts say what the warnings would have


@pytest.mark.slow
def test_dsg_hil_run_quiet_passes_it_to_the_ecu_stub_it_starts(tmp_path):
    """Two processes over udp_multicast: 'dsg-hil run -q' prints nothing of its own, its ecu-stub the counts alone
    (it printed its 'listening' line too)."""
    udp_bus()  # skips where this machine cannot do UDP multicast
    run = subprocess.run([*DSG_HIL, "run", "-q", "-i", "udp_multicast", "--duration", "1"], capture_output=True,
                         text=True, timeout=600, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ecu-stub: sent"), run.stderr


def test_quiet_and_verbose_exclude_each_other(capsys):
    with pytest.raises(SystemExit) as exc:
        _parse_args(["-i", "virtual", "-q", "-v"])
    assert exc.value.code == 2 and "not allowed with argument" in capsys.readouterr().err


def test_help_documents_quiet(capsys):
    with pytest.raises(SystemExit):
        _parse_args(["--help"])
    assert "-q, --quiet" in capsys.readouterr().out
