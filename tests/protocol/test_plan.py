"""The plan codec's own parts (:mod:`dsg_hil.protocol.plan`); its frames and values against the generated functions
and cantools: tests/protocol/test_generated_codec.py (``plans``), and compiled: tests/test_packaging.py."""

from __future__ import annotations

import os
import random

import pytest

from dsg_hil.common.build import EXPECT_ENV
from dsg_hil.protocol import generated, plan
from dsg_hil.protocol.codec import DecodedFrame, FrameError, load_dbc
from dsg_hil.protocol.e2e import Protection


def test_round_is_pythons_round_ties_to_even_negatives_and_large_values():
    rng = random.Random(4)
    values = [0.0, -0.0, 0.5, 1.5, 2.5, -0.5, -1.5, -2.5, 0.49999999999999994, -0.49999999999999994,
              0.5000000000000001, -0.5000000000000001, 2.0 ** 52 + 1, -(2.0 ** 52) - 1, 2.0 ** 60, 1e-300, -1e-300,
              4503599627370495.5, -4503599627370495.5]
    values += [rng.uniform(-1e6, 1e6) for _ in range(20000)]
    values += [(rng.randrange(-10 ** 6, 10 ** 6) + 0.5) * rng.choice((1.0, 0.1, 0.05, 0.0001)) for _ in range(20000)]
    values += [rng.uniform(-1.0, 1.0) * 10.0 ** rng.randrange(-20, 20) for _ in range(20000)]
    for x in values:
        assert plan._round(x) == round(x), x
        assert type(plan._round(x)) is int


def test_compiled_flag_is_the_module_file():
    """COMPILED: the module is an extension module (tests/test_packaging.py runs this on the wheel with
    DSG_HIL_EXPECT_COMPILED set: there it must be)."""
    assert plan.COMPILED == plan.__file__.endswith(".so")
    if os.environ.get(EXPECT_ENV, "") not in ("", "0"):
        assert plan.COMPILED, plan.__file__


def test_encode_values_takes_one_value_per_signal():
    message_plan = generated.plan(load_dbc().get_message_by_name("TCU_CMD"), Protection.of(
        load_dbc().get_message_by_name("TCU_CMD")), FrameError, DecodedFrame)
    assert message_plan is not None
    assert len(message_plan.encode_values((0.5, 0.25, 3.0, 0.1), 7)) == 8
    with pytest.raises(ValueError, match="TCU_CMD: 3 values for 4 signals"):
        message_plan.encode_values((0.5, 0.25, 3.0), 7)
