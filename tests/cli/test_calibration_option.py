"""``dsg-hil run --calibration FILE``: the bundled TCU's calibration, in this process or passed to the ecu-stub
process the run starts; a bad file fails at start (issue 20, item 9)."""

from __future__ import annotations

from pathlib import Path

import pytest

from dsg_hil.cli import main
from dsg_hil.common.errors import InputError
from dsg_hil.sim.run import EcuStubProcess, RunConfig, open_run
from ecu_stub.calibration import DEFAULT_CALIBRATION

GAIN = "kp_n_per_mps = { value = 80000.0,"


def softer(where: Path) -> Path:
    """The shipped calibration with half the speed controller's proportional gain."""
    text = DEFAULT_CALIBRATION.read_text(encoding="utf-8")
    assert GAIN in text
    path = where / "cal.toml"
    path.write_text(text.replace(GAIN, "kp_n_per_mps = { value = 40000.0,"), encoding="utf-8")
    return path


@pytest.mark.slow
def test_the_calibration_given_is_the_one_the_tcu_runs(tmp_path):
    cal = softer(tmp_path)
    for name, extra in (("default", []), ("same", ["--calibration", str(DEFAULT_CALIBRATION)]),
                        ("softer", ["--calibration", str(cal)])):
        assert main(["run", "-q", "--duration", "8", "--log", str(tmp_path / f"{name}.log"), *extra]) == 0
    logs = {name: (tmp_path / f"{name}.log").read_bytes() for name in ("default", "same", "softer")}
    assert logs["same"] == logs["default"] and logs["softer"] != logs["default"]


def test_a_tcu_process_is_started_with_it(tmp_path):
    cal = softer(tmp_path)
    config = RunConfig(bus={"interface": "udp_multicast", "channel": "239.255.1.2", "port": 40000}, calibration=cal)
    with open_run(config) as run:
        process = run._process
        assert isinstance(process, EcuStubProcess)
        argv = process.command(run.bus_config)
    assert argv[argv.index("--calibration") + 1] == str(cal.resolve())


def test_a_bad_calibration_or_one_for_another_tcu_fails_at_start(tmp_path, capsys):
    assert main(["run", "--calibration", str(tmp_path / "nosuch.toml"), "--log", str(tmp_path / "r.log")]) == 2
    assert capsys.readouterr().err.strip() == f"error: {tmp_path / 'nosuch.toml'}: cannot read calibration (No such " \
                                              f"file or directory)"
    assert not (tmp_path / "r.log").exists()
    with pytest.raises(InputError, match="is the bundled TCU's"):
        open_run(RunConfig(tcu=None, bus={"interface": "virtual", "channel": "x"}, calibration=DEFAULT_CALIBRATION))
