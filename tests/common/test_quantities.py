"""The {value, unit, source} entries shared by the parameter file and the TCU's calibration."""

from __future__ import annotations

import pytest

from dsg_hil.common.errors import InputError
from dsg_hil.common.quantities import finite, quantity

SOURCES = {"paper": "ref", "assumed": "why"}


class BadError(InputError):
    pass


def test_a_good_entry_gives_value_source_and_reason():
    raw = {"value": 2.5, "unit": "m", "source": "paper", "ref": "Table I"}
    assert quantity("a.b", raw, "m", SOURCES, BadError) == (2.5, "paper", "Table I")


@pytest.mark.parametrize(("raw", "needle"), [
    (2.5, r"a\.b: expected \{ value"),
    ({"value": 1, "unit": "m", "source": "paper", "ref": "x", "note": "y"}, r"a\.b\.note: unknown field"),
    ({"value": 1, "unit": "mm", "source": "paper", "ref": "x"}, "unit must be 'm', got 'mm'"),
    ({"value": 1, "unit": "m", "source": "guess", "ref": "x"}, "source must be one of paper, assumed"),
    ({"value": 1, "unit": "m", "source": "assumed", "ref": "x"}, "source 'assumed' needs a non-empty 'why'"),
    ({"value": 1, "unit": "m", "source": "paper", "ref": "  "}, "needs a non-empty 'ref'"),
])
def test_a_bad_entry_names_its_key_and_fault(raw, needle):
    with pytest.raises(BadError, match=needle):
        quantity("a.b", raw, "m", SOURCES, BadError)


@pytest.mark.parametrize(("value", "lo", "hi", "lo_open", "needle"), [
    (True, None, None, False, "finite number"), (float("nan"), None, None, False, "finite number"),
    ("1", None, None, False, "finite number"), (-1.0, 0.0, None, False, "must be >= 0.0"),
    (0.0, 0.0, None, True, "must be > 0.0"), (2.0, None, 1.0, False, "must be <= 1.0"),
])
def test_finite_checks_the_number_and_its_range(value, lo, hi, lo_open, needle):
    with pytest.raises(BadError, match=needle):
        finite("k", value, BadError, lo, hi, lo_open)
    assert finite("k", 3, BadError, 0.0, 3.0) == 3.0 and isinstance(finite("k", 3, BadError), float)
