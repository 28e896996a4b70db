"""The doors into ecu-stub's compiled runner: what an object handed to :class:`ecu_stub.runner.TcuRunner` must do.

The regular install compiles the runner with mypyc, which checks declared types at run time: a parameter typed
with a concrete class refuses any other object that has the same methods. So the runner declares these
:class:`typing.Protocol`\\ s, which every documented implementation satisfies: the bundled
:class:`~ecu_stub.controller.CreepController` (any calibration) and :class:`dsg_hil.fmi.controller.FmuController`
(a controller FMU). This module is pure Python (not compiled), so the protocols stay ordinary ones.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from dsg_hil.protocol.frame import FrameListener

if TYPE_CHECKING:  # the runtime does not need them: the protocols are structural
    from .controller import TcuInputs, TcuOutputs

__all__ = ["FrameListener", "SidePort", "TcuController"]


@runtime_checkable
class TcuController(Protocol):
    """What the runner drives each control period: ``update(inputs, now)`` turns the checked plant values
    (:class:`~ecu_stub.controller.TcuInputs`, SI and DBC units) at ``now`` [s] into the period's commands
    (:class:`~ecu_stub.controller.TcuOutputs`). ``cal`` is what the controller was built from: a lock-step start
    builds a fresh one as ``type(controller)(controller.cal)``. Where ``cal`` is an
    :class:`~ecu_stub.calibration.TcuCalibration` the runner also votes the speeds and checks the sensors with it, and
    a ``T_pred`` attribute (``{"CL": degC, "CH": degC}`` or None) lets the sensor checks bound the oil temperatures by
    the predicted plates."""

    @property
    def cal(self) -> Any: ...

    def update(self, inputs: TcuInputs, now: float) -> TcuOutputs: ...


class SidePort(Protocol):
    """A service beside the control loop on frames of its own (ecu-stub's XCP slave, :mod:`ecu_stub.xcp`): the
    runner hands it each classic frame on ``request_id`` (:meth:`take`) and calls :meth:`period` after each control
    period with the TCU's time [s]; it sends through the function it was built with."""

    @property
    def request_id(self) -> int: ...

    def take(self, data: bytes) -> None: ...

    def period(self, now: float) -> None: ...
