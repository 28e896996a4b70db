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
from dsg_hil.paper.holdout import BLOCKS
from dsg_hil.paper.report.model import model_checks
from dsg_hil.paper.validation import run_validation

QUICK_BLOCKS = tuple(b for b in BLOCKS if b.calibration == "pressure path")

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
           "fig11_pressures", "fig12_vehicle_speed", "fig13_sensitivity", "fig14_configurations")
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

    def checks(params, scenario, **kw):  # one calibration's hold-out, no assumed parameters screened: seconds
        return model_checks(params, scenario, blocks=QUICK_BLOCKS, assumed=[], **kw)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(report_cmd, "run_validation", validation)
        mp.setattr(report_cmd, "model_checks", checks)
        assert main(["report", "--out", str(base / "out"), "--scenario", str(scenario)]) == 0
    return base, base / "out", cases


@pytest.mark.slow
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
    assert data["summary_line"] in page and data["summary_line"].startswith("Section V.B: ")
    assert all(r["status"] in ("fitted", "predicted") for r in data["paper_vs_dsg_hil"])


def test_report_runs_the_table1_configuration_beside_the_main_one(run):
    _, out, _ = run
    data = json.loads((out / "report.json").read_text())
    assert (out / "table1" / "creep.log").stat().st_size > 0 and (out / "table1" / "summary.json").exists()
    conf = data["configurations"]
    assert conf["main"] == "fitted" and conf["table1"]["log"].endswith("creep.log")
    rows = {r["key"]: r for r in conf["section_vb"]}
    assert set(rows) == {r["key"] for r in data["paper_vs_dsg_hil"] if r["section"] == "V.B"} - {
        "max_plate_temp_c.CL", "max_plate_temp_c.CH"}
    assert all(r["reason"] for r in rows.values())
    assert rows["creep_time_s"]["given_loop"] == data["creep_time_s"]
    assert rows["creep_time_s"]["table1_loop"] == conf["table1"]["creep_time_s"]
    page = (out / "report.md").read_text()
    for section in ("## Hold-out check", "## Sensitivity", "## Configurations: fitted vs table1"):
        assert section in page
    checks = data["model_checks"]
    assert [h["key"] for h in checks["holdout"]] == [t.key for b in QUICK_BLOCKS for t in b.targets]
    assert len(checks["sensitivity"]["numbers"]) == 9


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


def test_the_phase_table_agrees_with_the_summary_from_the_launch_on(run):
    """The 100-ms SIM_* truth is interpolated onto the 10-ms grid, not held: held, phase 1 (a launch) started
    ~0.1 s late and its mu and P 'at the start' (0.5 s in) were read off a different point of the launch."""
    _, out, _ = run
    live = json.loads((out / "summary.json").read_text())["phases"]
    rep = json.loads((out / "report.json").read_text())["phases"]
    for a, b in zip(rep, live):
        assert a["start_s"] == pytest.approx(b["start_s"], abs=0.02)
        for key, tol in (("mu", 0.001), ("P_mpa", 0.015)):
            assert a[key]["start"] == pytest.approx(b[key]["start"], abs=tol), (key, a, b)
        assert a["T_CL_end_c"] == pytest.approx(b["T_CL_end_c"], abs=0.5)


@pytest.mark.slow
def test_from_log_of_the_recorded_run_gives_the_same_numbers(run, monkeypatch):
    base, out, cases = run
    monkeypatch.setattr(report_cmd, "run_validation", lambda params, **kw: cases)
    monkeypatch.setattr(report_cmd, "model_checks",
                        lambda params, scenario, **kw: model_checks(params, scenario, blocks=(), assumed=[], **kw))
    assert main(["report", "--from-log", str(out / "creep.log"), "--out", str(base / "again")]) == 0
    a = json.loads((out / "report.json").read_text())
    b = json.loads((base / "again" / "report.json").read_text())
    same = lambda d: {k: v for k, v in d.items() if k not in ("log", "model_checks", "configurations")}  # noqa: E731
    assert same(a) == same(b)
    assert b["configurations"]["table1"] is None  # no run on the loop with --from-log
    assert not (base / "again" / "creep.log").exists() and not (base / "again" / "table1").exists()


def test_an_asc_log_written_by_python_can_gives_the_same_numbers(run):
    base, out, _ = run
    asc = base / "creep.asc"
    with can.LogReader(str(out / "creep.log")) as reader, can.ASCWriter(str(asc)) as writer:
        for msg in reader:
            writer.on_message_received(msg)
    db = load_dbc()
    assert read_log(asc, db).metrics == read_log(out / "creep.log", db).metrics


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_unwritable_out_is_checked_before_the_run(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    proc = _cli("--out", str(blocker / "sub"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert proc.stderr.startswith("error: --out ") and "not a writable directory" in proc.stderr


@pytest.mark.slow
def test_a_log_without_sim_frames_gives_the_figures_without_truth(run):
    """A real ECU's log has no SIM_* frames: Fig. 8 says so instead of drawing an empty chart."""
    base, out, _ = run
    lines = (out / "creep.log").read_text().splitlines()
    bare = base / "no_sim.log"
    bare.write_text("\n".join(line for line in lines if not any(f" {i}#" in line for i in ("700", "701", "702", "7F0")))
                    + "\n")
    record = read_log(bare, load_dbc())
    assert not any(record.column("Q_CL") == record.column("Q_CL"))  # all NaN: no truth on this bus
    assert all(p.read_bytes()[:8] == PNG for p in creep_figures(record, base / "no_sim_figures"))
