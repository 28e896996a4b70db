"""The dsg-hil command line: outputs, files, and one-line errors with a non-zero exit."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from dsg_hil.cli import main


def test_validate_writes_json_and_plots(tmp_path, capsys):
    rc = main(["validate", "--json", str(tmp_path / "v.json"), "--plots", str(tmp_path / "plots")])
    out = capsys.readouterr().out
    assert rc == 3  # case 4's end torque is outside its band: reported, not hidden (README, 'Validation')
    assert "OUTSIDE BAND" in out and "torque_end_nm" in out
    data = json.loads((tmp_path / "v.json").read_text())
    assert len(data["cases"]) == 4 and data["cases"][3]["speed_rpm"] == 300.0
    for name in ("fig3_temperature.png", "fig4_torque.png", "fig5_mu.png", "friction_map.png"):
        assert (tmp_path / "plots" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_params_lists_sources(capsys):
    assert main(["params", "--source", "calibrated"]) == 0
    out = capsys.readouterr().out
    assert "friction.A_stribeck" in out and "thermal.clutch.h_plate_oil" in out and "2 calibrated" in out


@pytest.mark.parametrize("argv, message", [
    (["params", "--params", "/nonexistent/params.toml"], "cannot read parameter file"),
    (["validate", "--dt", "0"], "dt must be positive"),
])
def test_errors_are_one_line_without_traceback(argv, message):
    proc = subprocess.run([sys.executable, "-m", "dsg_hil", *argv], capture_output=True, text=True)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert lines[-1].startswith("error: ") and message in lines[-1]
    assert "Traceback" not in proc.stderr


def test_garbled_parameter_file(tmp_path):
    bad = tmp_path / "p.toml"
    bad.write_text("[friction]\nA_stribeck = { value = 0.03 }\n")
    proc = subprocess.run([sys.executable, "-m", "dsg_hil", "params", "--params", str(bad)],
                          capture_output=True, text=True)
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1 and "friction.A_stribeck" in proc.stderr


def test_help_explains_every_command():
    for cmd in ([], ["validate"], ["params"], ["calibrate"]):
        proc = subprocess.run([sys.executable, "-m", "dsg_hil", *cmd, "--help"], capture_output=True, text=True)
        assert proc.returncode == 0 and "usage:" in proc.stdout and len(proc.stdout) > 200
