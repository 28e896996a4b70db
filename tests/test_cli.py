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
    assert "friction.A_stribeck" in out and "thermal.clutch.test.h_plate_oil" in out
    assert "clutch.CL.C_plate" in out and "thermal.clutch.CH.Q_cool" in out and "10 calibrated" in out


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
    for cmd in ([], ["validate"], ["params"], ["calibrate"], ["run"], ["plant"], ["dbc"]):
        proc = subprocess.run([sys.executable, "-m", "dsg_hil", *cmd, "--help"], capture_output=True, text=True)
        assert proc.returncode == 0 and "usage:" in proc.stdout and len(proc.stdout) > 200


def test_run_on_virtual_writes_log_and_summary(tmp_path):
    log, summary = tmp_path / "run.log", tmp_path / "summary.json"
    proc = subprocess.run([sys.executable, "-m", "dsg_hil", "run", "--interface", "virtual", "--duration", "4",
                           "--log", str(log), "--summary", str(summary)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(summary.read_text())
    for key in ("creep_time_s", "slip_time_s", "max_plate_temp_c", "handovers", "stop_reason", "frames"):
        assert key in data
    assert set(data["slip_time_s"]) == {"CL", "CH"} and data["frames"]["sent"] > 1000
    lines = log.read_text().splitlines()
    assert lines[0].startswith("(0.000000) ") and "#" in lines[0]  # candump -L
    ids = {line.split()[2].split("#")[0] for line in lines}
    assert {"100", "200", "210", "7F0"} <= ids
    assert "done:" in proc.stderr


def test_dbc_command_prints_bus_load(capsys):
    assert main(["dbc"]) == 0
    out = capsys.readouterr().out
    assert "TCU_CMD" in out and "total at 500 kbit/s" in out


def test_ecu_stub_help_and_bad_interface():
    proc = subprocess.run([sys.executable, "-m", "ecu_stub", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and "creep strategy" in proc.stdout
    proc = subprocess.run([sys.executable, "-m", "ecu_stub", "--interface", "nosuchbus", "--duration", "0.1"],
                          capture_output=True, text=True)
    assert proc.returncode == 1 and proc.stderr.startswith("error: ") and "Traceback" not in proc.stderr


def test_run_with_bad_scenario_is_one_line(tmp_path):
    bad = tmp_path / "s.toml"
    bad.write_text("duration_s = 10\n[[driver]]\nt_s = 0\nbrake = 7\n")
    proc = subprocess.run([sys.executable, "-m", "dsg_hil", "run", "--scenario", str(bad)],
                          capture_output=True, text=True)
    assert proc.returncode == 1 and "driver[0].brake" in proc.stderr and "Traceback" not in proc.stderr
