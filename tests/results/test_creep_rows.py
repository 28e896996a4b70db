"""The compiled kernel's arrays addressed by name (dsg_hil.results.creep_rows)."""

from __future__ import annotations

import pytest

from dsg_hil.physics.plant import PlantOutputs
from dsg_hil.results.creep_rows import ACC, COLUMNS, RUN, SLOTS, Acc, Col, Run, Slot, columns


@pytest.mark.parametrize("names, index", [(COLUMNS, Col), (ACC, Acc), (RUN, Run), (SLOTS, Slot)])
def test_each_array_is_numbered_in_order_without_gaps_or_aliases(names, index):
    assert [int(member) for member in index] == list(range(len(index)))
    assert names == tuple(index.__members__) and len(set(names)) == len(names)


def test_the_columns_read_are_plant_outputs_and_found_by_name():
    cols = columns(PlantOutputs._fields)
    assert all(PlantOutputs._fields[cols[c]] == c.name for c in Col)
    with pytest.raises(ValueError):
        columns(("t", "v"))  # a trace without the columns the metrics need


def test_the_accumulators_pack_the_creep_metrics_by_name():
    from dsg_hil.results.summary import CreepMetrics

    m = CreepMetrics()
    m.slip_time["CH"], m.max_T["CL"], m.energy["CH"], m.creep_time, m.speed_min_creeping = 1.5, 240.0, 7.0, 3.0, 0.02
    acc = m._accumulators()
    assert acc[Acc.slip_CH] == 1.5 and acc[Acc.max_T_CL] == 240.0 and acc[Acc.energy_CH] == 7.0
    assert acc[Acc.creep] == 3.0 and acc[Acc.speed_min] == 0.02
    assert acc[Acc.max_T_CH] != acc[Acc.max_T_CH] and acc[Acc.rest_row] == -1.0  # None as NaN; no rest row yet
