"""dsg-hil report: a short creep run on the real loop, its figures, page and report.json; --from-log on the
recorded log (candump -L and .asc) gives the same numbers; bad inputs fail at once with one line."""

from __future__ import annotations

import json
import subprocess
import sys

import can
import pytest

from dsg_hil.cli import main, report_cmd
from dsg_hil.physics.plant import PlantOutputs
from dsg_hil.protocol import load_dbc
from dsg_hil.paper.report.figures import creep_figures
from dsg_hil.paper.report.log import read_log
from dsg_hil.paper.report.paper import PAPER
from dsg_hil.paper.validation import run_validation

# CL starts near its limit, CH warm: CL slips up to the limit and hands over to CH within 25 simulated seconds.
HOT = """name = "hot creep (test)"
duration_s = 25.0
[initial]
T_CL_c = 225.0
T_CH_c = 150.0
T_oil_c = 100.0
[[driver]]
t_s = 0.0
brake = 1.0
[[driver]]
t_s = 0.5
creep_request = true
desired_speed_mps = 0.2
"""
FIGURES = ("fig3_temperature", "fig4_torque", "fig5_mu", "fig8_heat_flux", "fig9_plate_temperatures", "fig10_mu",
           "fig11_pressures", "fig12_vehicle_speed")
CREEP_KEYS = ("creep_time_s", "slip_time_s", "T_CL_at_first_CH_limit_c", "T_CL_at_stop_c", "mu_CH_first_slip",
              "P_CH_first_slip_mpa", "max_plate_temp_c", "phases")
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One short report on the real loop; the validation cases are kept for the --from-log runs."""
    base = tmp_path_factory.mktemp("report")
    scenario = base / "hot.toml"
    scenario.write_text(HOT)
    cases = []

    def validation(params, **kw):
        cases.extend(run_validation(params, **kw))
        return cases

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(report_cmd, "run_validation", validation)
        assert main(["report", "--out", str(base / "out"), "--scenario", str(scenario)]) == 0
    return base, base / "out", cases


def test_report_writes_every_figure_the_page_and_report_json(run):
    _, out, _ = run
    for name in FIGURES:
        assert (out / "figures" / f"{name}.png").read_bytes()[:8] == PNG, name
    data = json.loads((out / "report.json").read_text())
    for key in CREEP_KEYS + ("cases", "paper_vs_dsg_hil"):
        assert key in data, key
    assert set(data["slip_time_s"]) == {"CL", "CH"} and set(data["max_plate_temp_c"]) == {"CL", "CH"}
    assert [p["clutch"] for p in data["phases"]][:2] == ["CL", "CH"]  # CL first, then the handover to CH
    assert all({"clutch", "start_s", "end_s"} <= set(p) for p in data["phases"])
    assert set(data["mu_CH_first_slip"]) == {"start", "end"} and set(data["P_CH_first_slip_mpa"]) == {"start", "end"}
    assert [c["case"] for c in data["cases"]] == [1, 2, 3, 4]
    assert set(data["cases"][0]) == {"case", "pressure_mpa", "speed_rpm", "temperature_rise_c", "torque_start_nm",
                                     "torque_end_nm", "mu_start", "mu_end"}  # as 'dsg-hil validate --json'
    assert len(data["paper_vs_dsg_hil"]) == len(PAPER)
    page = (out / "report.md").read_text()
    assert "| quantity | paper | dsg-hil | band | result |" in page
    for p in PAPER:
        assert p.label in page
    for name in FIGURES:
        assert f"(figures/{name}.png)" in page
    first = (out / "creep.log").read_text().splitlines()[0]
    assert first.startswith("(0.000000) ") and "#" in first  # candump -L


def test_report_numbers_agree_with_the_per_step_summary(run):
    """Same definitions, different sampling: every plant step (summary) vs the decoded log's 10 ms grid."""
    _, out, _ = run
    live = json.loads((out / "summary.json").read_text())
    rep = json.loads((out / "report.json").read_text())
    assert rep["creep_time_s"] == pytest.approx(live["creep_time_s"], abs=0.1)
    for c in ("CL", "CH"):
        assert rep["slip_time_s"][c] == pytest.approx(live["slip_time_s"][c], abs=0.15)
        assert rep["max_plate_temp_c"][c] == pytest.approx(live["max_plate_temp_c"][c], abs=0.2)
    assert [p["clutch"] for p in rep["phases"]] == [p["clutch"] for p in live["phases"]]
    for a, b in zip(rep["phases"], live["phases"]):
        assert a["start_s"] == pytest.approx(b["start_s"], abs=0.15)


def test_from_log_of_the_recorded_run_gives_the_same_numbers(run, monkeypatch):
    base, out, cases = run
    monkeypatch.setattr(report_cmd, "run_validation", lambda params, **kw: cases)
    assert main(["report", "--from-log", str(out / "creep.log"), "--out", str(base / "again")]) == 0
    a = json.loads((out / "report.json").read_text())
    b = json.loads((base / "again" / "report.json").read_text())
    assert {k: v for k, v in a.items() if k != "log"} == {k: v for k, v in b.items() if k != "log"}
    assert not (base / "again" / "creep.log").exists()  # no run: the given log only


def test_an_asc_log_written_by_python_can_gives_the_same_numbers(run):
    base, out, _ = run
    asc = base / "creep.asc"
    with can.LogReader(str(out / "creep.log")) as reader, can.ASCWriter(str(asc)) as writer:
        for msg in reader:
            writer.on_message_received(msg)
    db = load_dbc()
    assert read_log(asc, db).metrics == read_log(out / "creep.log", db).metrics


def test_a_log_without_tcu_status_gives_the_creep_numbers_and_figures(run):
    """A third-party ECU sends no TCU_STATUS: nothing but the predictions and the TCU's handovers is lost."""
    base, out, _ = run
    lines = (out / "creep.log").read_text().splitlines()
    other = base / "other_ecu.log"
    other.write_text("\n".join(line for line in lines if " 210#" not in line) + "\n")
    db = load_dbc()
    full, bare = read_log(out / "creep.log", db), read_log(other, db)
    assert bare.has_status is False and bare.metrics["max_predicted_temp_c"] == {"CL": None, "CH": None}
    for key in CREEP_KEYS:
        assert bare.metrics[key] == full.metrics[key], key
    assert all(p.read_bytes()[:8] == PNG for p in creep_figures(bare, base / "other_figures"))


def test_log_samples_carry_the_plant_output_names():
    from dsg_hil.paper.report.log import LogSample
    used = {"t", "v", "omega_in", "omega_CL", "omega_CH", "P_CL", "P_CH", "T_CL", "T_CH", "mu_CL", "mu_CH", "M_CL",
            "M_CH", "Q_CL", "Q_CH", "Q_diss_CL", "Q_diss_CH"}
    assert used <= set(LogSample._fields) and used <= set(PlantOutputs._fields)


def _cli(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dsg_hil", "report", *argv], capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("name, content, message", [
    ("missing.log", None, "log file not found"),
    ("garbled.log", "this is not a CAN log\n", "cannot read the log"),
    ("garbled.blf", "\x00\x01 not a blf", "cannot read the log"),
    ("empty.asc", "date Sun Nov 22 2026\nbase hex  timestamps absolute\n", "no frame of the DBC"),
])
def test_bad_log_is_one_error_line_before_any_run(tmp_path, name, content, message):
    log = tmp_path / name
    if content is not None:
        log.write_text(content)
    proc = _cli("--from-log", str(log), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2  # bad input
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("error: ") and message in proc.stderr
    assert str(log) in proc.stderr


def test_unwritable_out_is_checked_before_the_run(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    proc = _cli("--out", str(blocker / "sub"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert proc.stderr.startswith("error: --out ") and "not a writable directory" in proc.stderr
