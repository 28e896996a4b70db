"""ecu-stub's ``CreepController`` as an FMI 2.0 co-simulation FMU (``dsg-hil fmu export --model tcu``): the
controller direction's test piece, and an example of what a controller FMU for ``dsg-hil run --controller`` looks
like (the DBC's signals in and out, one ``doStep(t, h)`` one control cycle at ``t``: :mod:`dsg_hil.fmi.tcu`)."""

from __future__ import annotations

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Causality

from ecu_stub.controller import CreepController

from .signals import BUS_SIGNALS, TCU_INPUTS, TCU_OUTPUTS
from .slave import FmuCallError, SignalSlave
from .tcu import ValueTables, output_values, tcu_inputs

__all__ = ["TcuSlave"]


class TcuSlave(SignalSlave):
    """ecu-stub's ``CreepController`` behind the FMI 2.0 co-simulation interface: the DBC's signals in, the
    commands out; one ``doStep(t, h)`` is one control cycle at ``t`` (module docstring)."""

    description = "ecu-stub's creep controller (the TCU of dsg-hil) as a controller FMU. Needs dsg_hil installed."
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.01)
    model = "tcu"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._tables = ValueTables()
        for signal in TCU_INPUTS:
            self.signal(signal, Fmi2Causality.input)
        valid, faults = BUS_SIGNALS
        self.signal(valid, Fmi2Causality.input, 1.0,
                    "true: the plant's frames are present and valid (the bus side's receive checks)")
        self.signal(faults, Fmi2Causality.input, 0.0,
                    "protocol faults seen by the bus side (crc 0x02, counter 0x04, range 0x08)")
        for signal in TCU_OUTPUTS:
            self.signal(signal, Fmi2Causality.output)
        self.controller = CreepController()
        self.seal()

    def step(self, current_time: float, step_size: float) -> None:
        outputs = self.controller.update(tcu_inputs(self.values), current_time)
        self.values.update(output_values(outputs, self._tables))

    def snapshot(self) -> dict[str, Any]:
        """The controller's state is not in an FMU state: the FMU does not claim the capability (export.MODELS)."""
        raise FmuCallError("this FMU does not save its controller's state (canGetAndSetFMUstate is false)")
