"""The named parameter configurations: ``fitted`` (the shipped file, the default) and ``table1`` (Table I and stated
assumptions alone), resolved alike by the API, the CLI and the pytest fixture."""

from __future__ import annotations

from dataclasses import fields

import pytest

from dsg_hil.cli import main
from dsg_hil.paper.calibration import CALIBRATIONS
from dsg_hil.paper.report.paper import PAPER
from dsg_hil.physics.params import CONFIGURATIONS, DEFAULT_CONFIGURATION, load_params
from dsg_hil.sim.run import resolve_params

VB_KEYS = {p.key for p in PAPER if p.section == "V.B"}


@pytest.fixture(scope="module")
def table1():
    return load_params("table1")


def test_fitted_is_the_shipped_file_and_the_default(params):
    assert DEFAULT_CONFIGURATION == "fitted" and load_params("fitted") == params == resolve_params(None)


def test_table1_consumes_no_section_vb_number(table1):
    """Every quantity a V.B calibration set is re-sourced in table1 (paper or assumed, with its reason)."""
    vb_quantities = {q for c in CALIBRATIONS if set(c.targets) & VB_KEYS for q in c.quantities}
    for key in vb_quantities & set(table1.provenance):
        source, reason = table1.provenance[key]
        assert source in ("paper", "assumed") and reason, key
    assert not [k for k, (s, why) in table1.provenance.items() if s == "calibrated" and "V.B" in why]


def test_table1_has_identical_packs_and_one_cooling_model(table1):
    c, t = table1.clutch, table1.thermal.clutch
    assert c.CL == c.CH
    assert t.CL == t.CH
    assert (c.CL.R_i, c.CL.R_o, c.CL.A_f) == (c.test.R_i, c.test.R_o, c.test.A_f)  # Table I's disc and piston
    assert table1.powertrain.I_2 == table1.powertrain.I_3


def test_table1_differs_from_fitted_only_where_it_says(params, table1):
    changed = {key for key in table1.provenance if table1.provenance[key] != params.provenance[key]}
    assert changed == {key for key, (_, why) in table1.provenance.items() if why != params.provenance[key][1]}
    assert {"clutch.CL.C_plate", "clutch.CH.C_plate", "thermal.clutch.CL.Q_cool", "friction.A_stribeck"} <= changed
    for f in fields(params.vehicle):
        assert getattr(params.vehicle, f.name) == getattr(table1.vehicle, f.name)  # Table I's vehicle kept


def test_api_and_cli_resolve_the_same_names(table1, capsys):
    assert resolve_params("table1") == table1
    assert set(CONFIGURATIONS) == {"fitted", "table1"}
    assert main(["params", "--params", "table1"]) == 0
    listing = capsys.readouterr().out
    assert "clutch.CH.C_plate" in listing and "2620" in listing


def test_a_file_named_like_a_configuration_is_given_with_a_directory(tmp_path, monkeypatch):
    (tmp_path / "table1").write_text('[vehicle]\nm = { value = 9000.0, unit = "kg", source = "assumed", '
                                     'why = "test" }\n')
    monkeypatch.chdir(tmp_path)
    assert load_params("./table1").vehicle.m == 9000.0
    assert load_params("table1").vehicle.m != 9000.0


def test_the_pytest_fixture_resolves_the_name(dsg_hil_run):
    run = dsg_hil_run(duration=0.5, params="table1")
    assert run.summary["sim_time_s"] == pytest.approx(0.5, abs=0.011)
