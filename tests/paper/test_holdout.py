"""The hold-out check and the sensitivity table of the Section V.B calibrations (reduced model)."""

from __future__ import annotations

import math

import pytest

from dsg_hil.paper.calibration import CALIBRATIONS
from dsg_hil.paper.holdout import BLOCKS, hold_out
from dsg_hil.paper.report.paper import PAPER
from dsg_hil.paper.sensitivity import CALIBRATED, VB_TARGETS, Quantity, sensitivity
from dsg_hil.physics.params import load_params
from dsg_hil.sim.scenario import load_scenario

VB_KEYS = {p.key for p in PAPER if p.section == "V.B"}


@pytest.fixture(scope="module")
def scenario():
    return load_scenario()


def test_the_blocks_are_the_calibrations_that_consumed_vb_numbers():
    by_name = {c.name: c for c in CALIBRATIONS}
    for block in BLOCKS:
        assert {t.key for t in block.targets} == set(by_name[block.calibration].targets)
    consumed = {k for c in CALIBRATIONS for k in c.targets if k in VB_KEYS}
    assert {t.key for b in BLOCKS for t in b.targets} == consumed == {t.key for t in VB_TARGETS}


def test_a_determined_leave_one_out_refits_within_the_calibrations_bounds(params, scenario):
    """The pressure path: one free quantity (the mesh efficiency, <= 1 as in the file) for each remaining
    number: nothing fixed at a prior, each left-out P_CH predicted."""
    block = next(b for b in BLOCKS if b.calibration == "pressure path")
    rows = hold_out(params, scenario, blocks=(block,))
    assert [r.key for r in rows] == [t.key for t in block.targets]
    for r in rows:
        assert r.fixed == () and math.isfinite(r.predicted)
        (_, eta), = r.refit
        assert 0.0 < eta <= 1.0
        assert r.error == pytest.approx(r.predicted - r.published)


@pytest.mark.slow
def test_an_underdetermined_leave_one_out_fixes_a_quantity_at_its_table1_prior(params, scenario):
    """mu_CH: two unknowns (A, the CH slip), one number left: A is fixed at table1's value and named."""
    block = next(b for b in BLOCKS if b.calibration == "stribeck")
    rows = hold_out(params, scenario, blocks=(block,))
    prior = load_params("table1").friction.A_stribeck
    for r in rows:
        assert r.fixed == (("friction.A_stribeck", prior),)
        assert [q for q, _ in r.refit] == ["scenario creep speed"]


@pytest.mark.slow
def test_sensitivity_keeps_calibrated_columns_and_only_influential_assumed_ones(params, scenario):
    unused = Quantity("hydraulics.tau", ("hydraulics.tau",))  # the reduced model has no pressure lag
    oil = Quantity("oil.c_p", ("oil.c_p",))  # the cooling flows' heat capacity
    s = sensitivity(params, scenario, assumed=[unused, oil])
    assert s.quantities == tuple(q.name for q in CALIBRATED) + ("oil.c_p",)
    assert s.calibrated == (True,) * len(CALIBRATED) + (False,)
    assert s.screened == 2 and len(s.elasticity) == len(VB_TARGETS)
    column = s.quantities.index("clutch.CL/CH.N")
    mu_rows = [i for i, k in enumerate(s.numbers) if k.startswith("mu_")]
    p_rows = [i for i, k in enumerate(s.numbers) if k.startswith("P_")]
    for i, j in zip(mu_rows, p_rows):  # P = M / (mu N k): d ln P / d ln N = -1 - d ln mu / d ln N
        assert s.elasticity[j][column] == pytest.approx(-1.0 - s.elasticity[i][column], abs=0.02)
    assert s.top(1)[0][2] == max((e for row in s.elasticity for e in row if not math.isnan(e)), key=abs)
