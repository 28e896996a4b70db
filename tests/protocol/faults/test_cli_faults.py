"""Faults through the command line: dsg-hil run (TCU in process or started by it) and ecu-stub."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from dsg_hil.cli import main

FAULTS = ["--fault", "corrupt_crc:TCU_CMD@2-2.1", "--fault", "drop:PLANT_SPEEDS@2.2-2.3,p=0.5", "--fault-seed", "1"]


def test_run_with_faults_logs_the_same_frames_every_time(tmp_path):
    for name in ("a", "b"):
        argv = ["run", "-i", "virtual", "--duration", "2.5", "--log", str(tmp_path / f"{name}.log"),
                "--summary", str(tmp_path / f"{name}.json"), *FAULTS]
        assert main(argv) == 0
    assert (tmp_path / "a.log").read_bytes() == (tmp_path / "b.log").read_bytes()  # lockstep: bit for bit
    summary = json.loads((tmp_path / "a.json").read_text())
    faults = summary["faults"]
    assert faults["seed"] == 1 and faults["injected"]["corrupt_crc:TCU_CMD@2-2.1"] == 70
    assert 0 < faults["plant"]["drop:PLANT_SPEEDS@2.2-2.3"] < faults["injected"]["corrupt_crc:TCU_CMD@2-2.1"]
    assert summary["frames"]["by_message"]["TCU_CMD"]["rejected"] == {"crc": 70}  # detected by the plant
    assert summary["command_fallback"]["events"] == 1


@pytest.mark.slow
def test_run_passes_the_tcu_faults_to_the_ecu_stub_it_starts(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "dsg_hil", "run", "-i", "udp_multicast", "--duration", "1",
                           "--fault", "corrupt_crc:TCU_CMD@0.5-0.52", "--summary", str(tmp_path / "s.json")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "ecu-stub: faults injected (frames hit): corrupt_crc:TCU_CMD@0.5-0.52 4" in proc.stderr
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["faults"]["in_tcu_process"] == ["corrupt_crc:TCU_CMD@0.5-0.52"]
    # 2 ticks, 2 sends each: a fault the plant knows of costs one re-send a tick (RETRIES_IN_EPISODE), not 6
    assert summary["frames"]["by_message"]["TCU_CMD"]["rejected"] == {"crc": 4}
