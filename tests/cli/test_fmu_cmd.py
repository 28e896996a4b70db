"""``dsg-hil fmu export --params NAME`` and ``export_fmu(params=NAME)``: a configuration's name is accepted as
wherever a parameter file is (``--params table1`` was read as a file named 'table1', exit 1; the API raised
FileNotFoundError)."""

from __future__ import annotations

import pytest

from dsg_hil.cli import main
from dsg_hil.fmi.export import export_fmu
from dsg_hil.physics.params import load_params, value_of

fmpy = pytest.importorskip("fmpy", reason="the fmi extra")
pytest.importorskip("pythonfmu", reason="the fmi extra")


def _starts(path) -> dict[str, float]:
    md = fmpy.read_model_description(str(path))
    return {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}


@pytest.mark.parametrize("name", ["table1", "fitted"])
@pytest.mark.parametrize("door", ["command", "api"])
def test_a_configuration_s_name_gives_its_values_as_the_fmu_s_parameters(tmp_path, monkeypatch, name, door):
    monkeypatch.chdir(tmp_path)  # no file of that name here: the name is the configuration's
    if door == "command":
        assert main(["fmu", "export", "--out", "plant.fmu", "--params", name]) == 0
    else:
        assert export_fmu("plant.fmu", params=name).resolve() == tmp_path / "plant.fmu"
    starts, params = _starts(tmp_path / "plant.fmu"), load_params(name)
    for key in ("friction.A_stribeck", "clutch.CL.C_plate", "thermal.clutch.CH.Q_cool"):  # table1 differs in these
        assert starts[key] == pytest.approx(value_of(params, key), rel=1e-6), key
