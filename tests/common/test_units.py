"""The conversion constants (dsg_hil.common.units.CV) against hand values, and their round trips."""

from __future__ import annotations

import math
import random

import pytest

from dsg_hil.common.units import CV

PAIRS = [("RAD_S_TO_RPM", "RPM_TO_RAD_S"), ("MPA_TO_PA", "PA_TO_MPA"), ("KJ_TO_J", "J_TO_KJ"), ("KW_TO_W", "W_TO_KW"),
         ("S_TO_MS", "MS_TO_S"), ("FRACTION_TO_PERCENT", "PERCENT_TO_FRACTION")]


def test_values_by_hand():
    assert 1000.0 * CV.RPM_TO_RAD_S == pytest.approx(104.71975511965977)  # 1000 r/min
    assert CV.RAD_S_TO_RPM == pytest.approx(30.0 / math.pi, rel=1e-15)
    assert 0.75 * CV.MPA_TO_PA == 750000.0 and 250000.0 * CV.PA_TO_MPA == pytest.approx(0.25)
    assert 2140.0 * CV.W_TO_KW == pytest.approx(2.14) and 3.5 * CV.KJ_TO_J == 3500.0
    assert 10 * CV.MS_TO_S == pytest.approx(0.01) and 0.0123 * CV.S_TO_MS == pytest.approx(12.3)
    assert 0.3 * CV.FRACTION_TO_PERCENT == pytest.approx(30.0) and 50.0 * CV.PERCENT_TO_FRACTION == 0.5


def test_each_pair_is_inverse_and_the_speed_pair_exact_both_ways():
    for forward, backward in PAIRS:
        assert getattr(CV, forward) * getattr(CV, backward) == pytest.approx(1.0, rel=1e-15), forward
        assert getattr(CV, backward) == 1.0 / getattr(CV, forward)
    assert CV.RPM_TO_RAD_S == 2.0 * math.pi / 60.0  # the TCU's and the log reader's constant, to the last bit
    assert CV.MPA_TO_PA == 1e6 and CV.FRACTION_TO_PERCENT == 100.0  # exact: x / 1e6 and x * 100 round once


@pytest.mark.parametrize("forward, backward", PAIRS)
def test_round_trips(forward, backward):
    rng = random.Random(4)
    there, back = getattr(CV, forward), getattr(CV, backward)
    for _ in range(1000):
        x = rng.uniform(-1e4, 1e4)
        assert x * there * back == pytest.approx(x, rel=4e-16)
        assert x / there * there == pytest.approx(x, rel=4e-16)


def test_standard_library_only():
    import ast
    import inspect

    import dsg_hil.common.units as units

    tree = ast.parse(inspect.getsource(units))
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    imported |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert imported <= {"__future__", "math"}
