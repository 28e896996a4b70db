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


@pytest.mark.slow
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


@pytest.mark.slow
def test_a_log_of_another_matrix_is_plotted_through_its_binding(tmp_path, capsys):
    """A run on the dct_fd example (CAN FD, AUTOSAR E2E Profiles 5 and 11, a multiplexed message, other units:
    km/h, bar with an offset, K): with ``--binding`` every panel's quantity is read from the signal that carries
    it and shown in the shipped signal's unit: the plate temperatures (K on the bus) are the log's values less
    273.15, the desired speed (km/h on the bus) the scenario's within half its step; without it, the frames fail
    the shipped DBC's checks and nothing is plotted."""
    import json
    from importlib import resources

    from dsg_hil.protocol.binding import load_binding
    from dsg_hil.protocol.logs import decoded_frames, log_codec
    from dsg_hil.sim.scenario import load_scenario

    example = resources.files("dsg_hil") / "data" / "examples" / "dct_fd"
    dbc, binding = str(example / "dct_fd.dbc"), str(example / "dct_fd.binding.toml")
    log, summary = tmp_path / "dct_fd.log", tmp_path / "summary.json"
    assert main(["run", "-q", "--duration", "3", "--dbc", dbc, "--binding", binding, "--log", str(log),
                 "--summary", str(summary)]) == 0
    run = json.loads(summary.read_text(encoding="utf-8"))
    pair = load_binding(binding, dbc=dbc)
    data = series(log, load_dbc(dbc), pair)
    assert set(data) == {key for _, _, signals in PANELS for key, _ in signals}

    def step(message: str, signal: str) -> float:
        return float(pair.db.get_message_by_name(message).get_signal_by_name(signal).scale)

    on_bus: dict[str, list[float]] = {}  # the log's own values of the signals, in their units (K)
    for _, frame in decoded_frames(log, log_codec(pair.db, pair.protection)):
        for signal in ("T_PlateA", "T_ClutchA_Est"):
            if frame is not None and signal in frame.values:
                on_bus.setdefault(signal, []).append(frame.values[signal])
    assert data["SIM_TRUTH_CL.T_Plate"][1] == pytest.approx([k - 273.15 for k in on_bus["T_PlateA"]], abs=1e-9)
    assert data["TCU_STATUS.T_CL_Pred"][1] == pytest.approx([k - 273.15 for k in on_bus["T_ClutchA_Est"]], abs=1e-9)
    assert max(data["SIM_TRUTH_CL.T_Plate"][1]) > 105.0 and run["max_plate_temp_c"]["CL"] > 105.0  # (it slipped)
    desired = max(d.desired_speed_mps for d in load_scenario().driver)
    assert max(data["DRIVER.DesiredCreepSpeed"][1]) == pytest.approx(
        desired, abs=step("DRV_Demand", "CreepSpdTarget") / 3.6 / 2 + 1e-9)
    assert max(data["PLANT_PRESSURE.P_CL"][1]) > 0.3  # MPa (bar on the bus, offset -1 bar)
    assert main(["plot", str(log), "--dbc", dbc, "--binding", binding, "-o", str(tmp_path / "fd.png")]) == 0
    assert (tmp_path / "fd.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    capsys.readouterr()
    assert main(["plot", str(log), "--dbc", dbc, "-o", str(tmp_path / "no.png")]) == 2
    assert "none of the signals plotted" in capsys.readouterr().err and not (tmp_path / "no.png").exists()
