"""The dsg_hil pytest plugin and dsg_hil.testing: the three kinds of controller, what a run gives, its errors."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import can
import numpy as np
import pytest

from dsg_hil.common.errors import InputError
from dsg_hil.protocol import load_dbc
from dsg_hil.sim.runner import PeerTimeout
from dsg_hil.testing import ControllerProcess, run_plant

ECU_STUB = [sys.executable, "-m", "ecu_stub", "{bus_args}"]  # the real ecu-stub command line


def frame_tuples(frames):
    return [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in frames]


@pytest.fixture(scope="module")
def bundled(dsg_hil_run):
    return dsg_hil_run(duration=3.0)


def test_the_bundled_ecu_stub_run_gives_summary_signals_truth_and_log(bundled):
    run, db = bundled, load_dbc()
    assert run.summary["frames"]["rejected"] == 0 and run.summary["frames"]["unanswered_ticks"] == 0
    for message in db.messages:  # every DBC signal, decoded, on its message's time axis
        n = len(run.signals[f"{message.name}.t"])
        assert n > 0, message.name
        assert all(len(run.signals[f"{message.name}.{s.name}"]) == n for s in message.signals)
    assert len(run.signals["PLANT_VEHICLE.t"]) == 300 and len(run.signals["PLANT_OIL_TEMP.t"]) == 30
    assert np.allclose(np.diff(run.truth["t"]), 0.01) and len(run.truth["t"]) == 300
    # the bus carries the truth, quantised to the DBC's 1 mm/s, at the same instants
    assert np.max(np.abs(run.signals["PLANT_VEHICLE.VehicleSpeed"] - run.truth["v"])) <= 0.0005 + 1e-9
    logged = list(can.LogReader(str(run.log)))
    assert run.log.suffix == ".asc" and len(logged) == len(run.frames)
    assert [bytes(m.data) for m in logged] == [bytes(m.data) for m in run.frames]
    assert {m.channel for m in logged} in ({"vcan0"}, {0}, {1})  # ASC writes channel numbers


def test_signals_at_holds_the_last_frame():
    from dsg_hil.testing import Signals

    s = Signals({"M.t": np.array([0.0, 0.1]), "M.x": np.array([1.0, 2.0])})
    assert np.array_equal(s.at("M.x", np.array([-0.01, 0.0, 0.05, 0.1, 5.0])), [np.nan, 1, 1, 2, 2], equal_nan=True)


@pytest.mark.slow
def test_ecu_stub_as_a_process_on_udp_multicast_gives_the_in_process_frames(dsg_hil_run, bundled):
    run = dsg_hil_run(ECU_STUB, duration=3.0)
    assert "ecu-stub: listening on udp_multicast:239.255." in run.controller_output.read_text()
    assert run.summary["frames"]["received"] > 0
    assert frame_tuples(run.frames) == frame_tuples(bundled.frames)  # lockstep: bit for bit, whichever process


class Recorder:
    """A Python controller: a fixed CL pressure once the driver asks to creep; records what it saw."""

    def __init__(self) -> None:
        self.calls: list[tuple[float, dict]] = []

    def step(self, t, inputs):
        self.calls.append((t, {name: dict(values) for name, values in inputs.items()}))
        return {"P_CL_Cmd": 0.9 if inputs["DRIVER"]["CreepRequest"] else 0.0}


def test_a_python_controller_is_stepped_once_per_period_with_decoded_plant_frames(dsg_hil_run):
    controller = Recorder()
    run = dsg_hil_run(controller, duration=2.0, log=None)
    assert run.log is None
    assert [t for t, _ in controller.calls] == pytest.approx([k * 0.01 for k in range(200)])
    t, inputs = controller.calls[150]
    assert set(inputs) == {"PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP",
                           "DRIVER"}
    assert inputs["DRIVER"]["DesiredCreepSpeed"] == pytest.approx(0.206)
    assert inputs["PLANT_VEHICLE"]["VehicleSpeed"] == pytest.approx(run.truth["v"][150], abs=0.0005)
    cmd = run.signals["TCU_CMD.P_CL_Cmd"]
    assert len(cmd) == 200 and cmd[50] == 0.0 and cmd[-1] == pytest.approx(0.9)
    assert len(run.signals["TCU_STATUS.t"]) == 0  # no status() method: no TCU_STATUS
    assert run.truth["P_CL"][-1] > 0.8e6  # the plant followed the command (Pa)


def test_params_faults_and_scenario_are_arguments(dsg_hil_run):
    heavy = dsg_hil_run(duration=2.0, params={"vehicle.m": 2500.0}, faults=["drop:TCU_CMD@1.5-1.6"], log=None)
    assert heavy.summary["faults"]["injected"] == {"drop:TCU_CMD@1.5-1.6": 70}
    assert heavy.summary["command_fallback"]["events"] == 1
    light = dsg_hil_run(duration=2.0, params={"vehicle.m": 1000.0}, log=None)
    assert light.truth["v"][140] > heavy.truth["v"][140]  # the same pressures move the lighter car faster
    with pytest.raises(InputError, match="vehicle.mass"):
        run_plant(duration=0.1, params={"vehicle.mass": 1.0}, log=None)


@pytest.mark.slow
def test_a_controller_process_that_never_answers_fails_clearly(tmp_path):
    silent = ControllerProcess([sys.executable, "-c", "import time; time.sleep(60)"])
    with pytest.raises(PeerTimeout, match="no TCU answered.*still running"):
        run_plant(silent, duration=1.0, out_dir=tmp_path, startup_timeout=1.0)
    with pytest.raises(PeerTimeout, match="exited with status 3; its output: bye"):
        run_plant([sys.executable, "-c", "print('bye'); raise SystemExit(3)"], duration=1.0, log=None,
                  startup_timeout=2.0)


def test_command_placeholders_and_environment(tmp_path):
    config = {"interface": "udp_multicast", "channel": "239.255.1.2", "port": 40000}
    process = ControllerProcess(["ecu", "{bus_args}", "--group={channel}:{port}"])
    assert process.command(config) == ["ecu", "-i", "udp_multicast", "-c", "239.255.1.2", "--bus-kwargs",
                                       "port=40000", "--group=239.255.1.2:40000"]
    env_check = ("import can.util, json; c = can.util.load_config(); "
                 "print(json.dumps([c['interface'], c['channel'], c['port']]))")
    process = ControllerProcess([sys.executable, "-c", env_check])
    with open(tmp_path / "out", "wb") as sink:
        assert process.start(config, sink).wait(timeout=60) == 0
    assert (tmp_path / "out").read_text().strip() == '["udp_multicast", "239.255.1.2", 40000]'


def test_the_plugin_imports_nothing_heavy_and_is_declared():
    code = ("import sys, dsg_hil.testing.plugin; "
            "print(sorted(m for m in ('numpy', 'can', 'cantools', 'scipy', 'dsg_hil.testing.harness') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
    if pyproject.exists():  # a checkout or the sdist
        declared = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]["entry-points"]["pytest11"]
        assert declared == {"dsg_hil": "dsg_hil.testing.plugin"}
    for entry in metadata.entry_points(group="pytest11", name="dsg_hil"):  # installed
        assert entry.value == "dsg_hil.testing.plugin"


def test_the_fixture_takes_a_dbc_and_its_binding(bundled, dsg_hil_run, tmp_path):
    """The shipped pair given by path runs the frames of the default, bit for bit; a binding the DBC cannot carry
    fails at start, naming the file."""
    from dsg_hil.protocol.binding import DEFAULT_BINDING, BindingError
    from dsg_hil.protocol.codec import DEFAULT_DBC

    given = dsg_hil_run(duration=3.0, dbc=str(DEFAULT_DBC), binding=str(DEFAULT_BINDING), log=None)
    assert frame_tuples(given.frames) == frame_tuples(bundled.frames)
    bad = tmp_path / "bad.binding.toml"
    bad.write_text(DEFAULT_BINDING.read_text(encoding="utf-8").replace('v = "PLANT_VEHICLE.VehicleSpeed"',
                                                                       'v = "PLANT_VEHICLE.Speed"'), encoding="utf-8")
    with pytest.raises(BindingError, match="bad.binding.toml: quantities.v: signal PLANT_VEHICLE.Speed"):
        dsg_hil_run(duration=1.0, binding=bad, log=None)
