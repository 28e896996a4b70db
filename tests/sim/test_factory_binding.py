"""A controller in this process (``RunConfig.tcu``, a factory) on a binding's matrix: ecu-stub's controller object
runs on the binding's messages as the bundled TCU does (its factory takes ``io``); a :class:`dsg_hil.testing.Controller`
(``step(t, inputs)``, inputs by the shipped DBC's message and signal names) cannot, and is one error naming the binding
file before anything opens (before: "message PLANT_ENGINE is not in the DBC", naming neither the binding nor the
controller); on a binding that leaves the TCU's frames as shipped it still runs."""

from __future__ import annotations

from collections.abc import Mapping
from importlib import resources
from pathlib import Path

import pytest

from dsg_hil.common.errors import InputError
from dsg_hil.protocol.binding import DEFAULT_BINDING
from dsg_hil.testing import run_plant
from ecu_stub.controller import CreepController

EXAMPLE = resources.files("dsg_hil") / "data" / "examples" / "dct_fd"
DBC, BINDING = Path(str(EXAMPLE / "dct_fd.dbc")), Path(str(EXAMPLE / "dct_fd.binding.toml"))


class Hold:
    """A Controller holding both clutches open."""

    def __init__(self) -> None:
        self.steps = 0

    def step(self, t: float, inputs: Mapping[str, Mapping[str, float]]) -> Mapping[str, float]:
        self.steps += 1
        return {"P_CL_Cmd": 0.0, "P_CH_Cmd": 0.0}


def sent(run) -> list[tuple[int, bytes]]:
    return [(m.arbitration_id, bytes(m.data)) for m in run.frames]


def test_ecu_stub_s_controller_object_runs_on_the_binding_s_matrix():
    mine = run_plant(CreepController(), duration=1.0, log=None, dbc=DBC, binding=BINDING)
    bundled = run_plant(None, duration=1.0, log=None, dbc=DBC, binding=BINDING)
    assert sent(mine) == sent(bundled)
    assert sum(frame_id == 452 for frame_id, _ in sent(mine)) >= 95  # TCU_Demand (0x1C4), dct_fd's command


def test_a_step_controller_on_another_matrix_is_one_error_naming_the_binding():
    controller = Hold()
    with pytest.raises(InputError) as raised:
        run_plant(controller, duration=1.0, log=None, dbc=DBC, binding=BINDING)
    assert f"--binding {BINDING}: moves the TCU's frames off the shipped DBC's" in str(raised.value)
    assert "give one taking io" in str(raised.value) and controller.steps == 0


def test_a_step_controller_runs_on_a_binding_that_keeps_the_shipped_frames():
    controller = Hold()
    run = run_plant(controller, duration=0.5, log=None, binding=DEFAULT_BINDING)
    assert controller.steps >= 45 and run.summary["stop_reason"] == "end_of_record"
