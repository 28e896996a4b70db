"""``dsg-hil plot LOG -o FILE``: one run's speed, pressures and plate temperatures from its log alone."""

from __future__ import annotations

import pytest

from dsg_hil.cli import main
from dsg_hil.cli.plot_cmd import PANELS, series
from dsg_hil.protocol import load_dbc

pytest.importorskip("matplotlib", reason="the plots extra is not installed")


@pytest.fixture(scope="module")
def run_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("plot") / "run.log"
    assert main(["run", "-q", "--duration", "3", "--log", str(path)]) == 0
    return path


def test_every_panel_signal_of_a_run_is_read_from_its_log(run_log):
    data = series(run_log, load_dbc())
    assert set(data) == {key for _, _, signals in PANELS for key, _ in signals}  # a run of dsg-hil has them all
    times, speeds = data["PLANT_VEHICLE.VehicleSpeed"]
    assert times[0] == 0.0 and times[-1] == pytest.approx(2.99, abs=0.02) and max(speeds) > 0.1  # it crept


def test_plot_writes_the_image_by_its_extension(run_log, tmp_path, capsys):
    assert main(["plot", str(run_log), "-o", str(tmp_path / "run.png")]) == 0
    assert (tmp_path / "run.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["plot", str(run_log), "--output", str(tmp_path / "run.svg")]) == 0
    assert b"<svg" in (tmp_path / "run.svg").read_bytes()[:1000]
    assert capsys.readouterr().err.splitlines() == [f"wrote {tmp_path / 'run.png'}", f"wrote {tmp_path / 'run.svg'}"]


def test_a_log_of_another_bus_is_one_error_and_no_image(tmp_path, capsys):
    log = tmp_path / "other.log"
    log.write_text("(0.0) can0 123#0011\n(0.1) can0 124#0011\n", encoding="utf-8")
    assert main(["plot", str(log)]) == 2
    assert capsys.readouterr().err.strip().startswith(f"error: {log}: none of the signals plotted")
    assert not (tmp_path / "other.png").exists()
