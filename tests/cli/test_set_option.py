"""``--set KEY=VALUE`` and partial ``--params`` files on the commands: applied to the run, listed with their
provenance by ``dsg-hil params``, and bad ones rejected with exit 2 and one line naming ``--set`` and the key."""

from __future__ import annotations

import pytest

from dsg_hil.cli import _parse_args, main
from dsg_hil.cli.busopts import run_config

PARTIAL = ('[vehicle]\nm = { value = 9000.0, unit = "kg", source = "assumed", why = "a loaded bus, not the '
           'paper\'s" }\n')


def one_error_line(capsys, *needles: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert all(needle in err[0] for needle in needles), err[0]
    return err[0]


@pytest.mark.parametrize("command", ["run", "plant"])
def test_set_reaches_the_run(tmp_path, command):
    args = _parse_args([command, "-i", "virtual", "--set", "vehicle.m=9000", "--set", "clutch.CL.N=8 1",
                        "--log", str(tmp_path / "run.log")])
    params = run_config(args).params
    assert params.vehicle.m == 9000.0 and params.clutch.CL.N == 8.0
    assert params.vehicle.g == pytest.approx(9.81, rel=1e-3)  # the rest as shipped
    assert not (tmp_path / "run.log").exists()  # a config opens nothing


def test_later_set_wins_and_set_comes_after_params(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(PARTIAL, encoding="utf-8")
    args = _parse_args(["run", "-i", "virtual", "--params", str(path), "--set", "vehicle.m=8000[kg]",
                        "--set", "vehicle.m=8500"])
    assert run_config(args).params.vehicle.m == 8500.0


def test_params_lists_an_override_with_its_provenance(capsys):
    assert main(["params", "--set", "vehicle.m=9000 kg"]) == 0
    out = capsys.readouterr().out.splitlines()
    line = next(line for line in out if line.startswith("vehicle.m "))
    assert line.split()[1:4] == ["9000", "kg", "override"]
    assert "--set vehicle.m=9000 (was 7840, paper)" in line
    assert "1 override" in out[-1]


def test_params_lists_a_partial_file_layered_on_the_shipped_one(tmp_path, capsys):
    path = tmp_path / "p.toml"
    path.write_text(PARTIAL, encoding="utf-8")
    assert main(["params", "--params", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert next(line for line in out if line.startswith("vehicle.m ")).split()[1:4] == ["9000", "kg", "assumed"]
    assert next(line for line in out if line.startswith("vehicle.f ")).split()[1:4] == ["0.123", "1", "paper"]
    assert "override" not in out[-1]


@pytest.mark.parametrize("assignment, needles", [
    ("vehicle.m=-5", ("--set vehicle.m", "out of range")),
    ("vehicle.beta=1", ("--set vehicle.beta", "out of range")),
    ("clutch.CL.N=6.5", ("--set clutch.CL.N", "whole number")),
    ("vehicle.mass=9000", ("--set: no parameter 'vehicle.mass'",)),
    ("vehicle=9000", ("--set: no parameter 'vehicle'",)),
    ("provenance.x=1", ("--set: no parameter 'provenance.x'",)),
    ("vehicle.m=heavy", ("--set vehicle.m", "finite number")),
    ("vehicle.m=nan", ("--set vehicle.m", "finite number")),
    ("vehicle.m=9 t", ("--set vehicle.m", "unit must be 'kg'", "'t'")),
    ("vehicle.m=9000[lb]", ("--set vehicle.m", "unit must be 'kg'")),
    ("vehicle.m", ("--set", "KEY=VALUE")),
    ("clutch.test.R_i=0.2", ("--set", "clutch.test.R_i", "R_o")),
])
@pytest.mark.parametrize("command", ["run", "params"])
def test_bad_set_is_exit_2_naming_it_and_writes_nothing(tmp_path, capsys, command, assignment, needles):
    out = ["--summary", str(tmp_path / "s.json"), "--log", str(tmp_path / "run.log")] if command == "run" else []
    assert main([command, "--set", assignment, *out]) == 2
    one_error_line(capsys, *needles)
    assert list(tmp_path.iterdir()) == []


def test_bad_set_on_report_writes_nothing(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    out = tmp_path / "rep"
    assert main(["report", "--out", str(out), "--set", "vehicle.m=0"]) == 2
    one_error_line(capsys, "--set vehicle.m", "out of range")
    assert not out.exists()
