"""The FMU side of ecu-stub's controller outputs (:mod:`dsg_hil.fmi.tcu`)."""

from __future__ import annotations

import pytest

from dsg_hil.fmi.tcu import OPTIONAL_OUTPUTS, ValueTables, output_values, tcu_outputs
from ecu_stub.controller import TcuOutputs


def test_the_outputs_round_trip_and_the_deceleration_request_is_optional():
    tables = ValueTables()
    out = TcuOutputs(0.5, 0.0, "CREEP", "CL", False, 187.4, 101.2, 0, 0.35)
    values = output_values(out, tables)
    assert values["DecelRequest"] == 0.35 and tcu_outputs(values, tables) == out
    del values["DecelRequest"]  # a controller FMU without one: no deceleration asked
    assert tcu_outputs(values, tables).decel_request_mps2 == OPTIONAL_OUTPUTS["DecelRequest"] == 0.0
    del values["P_CL_Cmd"]  # a required one is still required
    with pytest.raises(KeyError):
        tcu_outputs(values, tables)
