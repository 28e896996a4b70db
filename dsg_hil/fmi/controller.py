"""A controller FMU as the TCU: FMPy runs a co-simulation FMU (FMI 2.0, e.g. exported from Simulink) behind
ecu-stub's bus side, so its commands go over CAN like any ECU's (counters, CRC, SyncEcho, receive checks and
lock-step answers are ecu-stub's, :class:`ecu_stub.runner.TcuRunner`)::

    with open_controller("my_tcu.fmu") as fmu:
        with open_run(RunConfig(tcu=fmu.tcu_factory)) as run:
            summary = run.run()

The FMU's variables are matched to the DBC's by name (:data:`~dsg_hil.fmi.signals.TCU_INPUTS`, ``TCU_OUTPUTS``,
plus ``PlantValid`` and ``RxFaultBits`` from the receive checks), or through a mapping ``{FMU variable: DBC
signal}`` (a TOML file of ``"FMU name" = "DBC signal"`` lines). Every FMU input must be one of those, every TCU
output (TCU_CMD's pressures, TCU_STATUS's signals) an FMU output but ``DecelRequest`` (optional: 0, no deceleration
asked, without one). A port may be a Real (the DBC's physical value and unit), an Integer (a whole number: State,
ActiveClutch, bit fields) or a Boolean (a flag); a mapping key that names no port of the FMU is an error. Each control
cycle at ``now`` sets the inputs and calls ``doStep(now, cycle)`` (``cycle``: the DBC's TCU_CMD cycle time); the
outputs are the cycle's commands (:mod:`dsg_hil.fmi.tcu`).

One instance per controller: a new run resets it (fmi2Reset) rather than instantiating another.
"""

from __future__ import annotations

import shutil
import tomllib
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import Any, cast

import can
from cantools.database.can import Database

from ecu_stub.controller import CreepController, TcuInputs, TcuOutputs
from ecu_stub.runner import TCU_USES, TcuRunner
from ecu_stub.tcu_io import TcuIO

from ..common.errors import InputError, RunError
from ..common.files import read_input_file
from ..protocol import Codec
from .host import KINDS, Ref, get_values, instantiate, set_values
from .signals import BUS_INPUTS, TCU_INPUTS, TCU_OUTPUTS
from .tcu import OPTIONAL_OUTPUTS, ValueTables, input_values, tcu_outputs

__all__ = ["ControllerFmu", "FmuController", "FmuError", "load_mapping", "open_controller"]


class FmuError(InputError):
    """A controller FMU that cannot be used: unreadable, not FMI 2.0 co-simulation, or a variable that matches no
    DBC signal."""


def load_mapping(path: str | Path) -> dict[str, str]:
    """A mapping file: TOML ``"FMU variable" = "DBC signal"`` lines (optionally under ``[signals]``)."""
    text = read_input_file(Path(path), "mapping file", FmuError)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FmuError(f"{path}: not TOML ({exc})") from exc
    table = data.get("signals", data)
    bad = [key for key, value in table.items() if not isinstance(value, str)]
    if bad:
        raise FmuError(f"{path}: {bad[0]}: expected \"FMU variable\" = \"DBC signal\"")
    return dict(table)


class ControllerFmu:
    """A controller FMU opened through FMPy, its variables checked against the DBC's (module docstring). A context
    manager: leaving it frees the instance and the extracted files."""

    def __init__(self, path: str | Path, mapping: Mapping[str, str] | None = None, cycle: float = 0.01) -> None:
        self.path, self.cycle = Path(path), cycle
        if not self.path.is_file():
            raise FmuError(f"--controller {self.path}: no such file")
        try:
            from fmpy import extract, read_model_description  # noqa: PLC0415 - the fmi extra, when an FMU is used
        except ImportError as exc:
            raise FmuError(f"--controller needs the fmi extra: pip install 'dsg-hil[fmi]' ({exc})") from exc
        try:
            description = read_model_description(str(self.path))
        except Exception as exc:  # noqa: BLE001 - FMPy raises anything from zip, XML and schema errors
            raise FmuError(f"{self.path}: not a readable FMU ({exc})") from exc
        if description.fmiVersion != "2.0" or description.coSimulation is None:
            raise FmuError(f"{self.path}: FMI {description.fmiVersion} without FMI 2.0 co-simulation (needed: a "
                           f"co-simulation FMU, FMI 2.0)")
        self.inputs, self.outputs = self._match(description, dict(mapping or {}))
        self._description = description
        self._unzipped = extract(str(self.path))
        self._fmu: Any = None
        self.tables = ValueTables()

    def _match(self, description: Any, mapping: dict[str, str]) -> tuple[dict[str, Ref], dict[str, Ref]]:
        """{DBC signal: (FMI type, value reference)} of the FMU's inputs and outputs; a mismatch is one FmuError
        naming it (the DBC signal a mapping names, a mapping key that names no input or output)."""
        readable = {s.name for s in TCU_INPUTS} | set(BUS_INPUTS)
        writable = {s.name for s in TCU_OUTPUTS}
        inputs: dict[str, Ref] = {}
        outputs: dict[str, Ref] = {}
        ports = [v for v in description.modelVariables if v.causality in ("input", "output")]
        unused = sorted(set(mapping) - {v.name for v in ports})
        if unused:
            raise FmuError(f"{self.path}: the mapping's key {unused[0]!r} is no input or output variable of the FMU "
                           f"(its ports: {', '.join(v.name for v in ports)})")
        for variable in ports:
            signal = mapping.get(variable.name, variable.name)
            reads = variable.causality == "input"
            known = readable if reads else writable
            if signal not in known:
                named = (f"the mapping's DBC signal {signal!r} (for {variable.causality} variable "
                         f"{variable.name!r})" if variable.name in mapping else
                         f"{variable.causality} variable {variable.name!r}")
                raise FmuError(f"{self.path}: {named} matches no DBC signal the TCU {'reads' if reads else 'sends'} "
                               f"(known: {', '.join(sorted(known))}; or map it in a mapping file)")
            if variable.type not in KINDS:
                raise FmuError(f"{self.path}: variable {variable.name!r} is {variable.type}: a DBC signal's variable "
                               f"is a Real (the physical value), an Integer or a Boolean")
            side = inputs if reads else outputs
            if signal in side:
                other = next(v.name for v in ports if v.valueReference == side[signal][1]
                             and v.causality == variable.causality and v.type == side[signal][0])
                raise FmuError(f"{self.path}: {other!r} and {variable.name!r} both map to the DBC signal {signal!r}")
            side[signal] = (variable.type, variable.valueReference)
        missing = [name for name in sorted(writable) if name not in outputs and name not in OPTIONAL_OUTPUTS]
        if missing:
            raise FmuError(f"{self.path}: no output variable for the DBC signal {missing[0]!r} (the TCU sends "
                           f"{', '.join(sorted(writable))}; or map one in a mapping file)")
        return inputs, outputs

    def start(self) -> None:
        """Initialise the FMU for a run: instantiated the first time, reset after."""
        from fmpy.fmi2 import FMU2Slave  # noqa: PLC0415

        try:
            if self._fmu is None:
                d = self._description
                self._fmu = FMU2Slave(guid=d.guid, unzipDirectory=self._unzipped,
                                      modelIdentifier=d.coSimulation.modelIdentifier, instanceName="tcu")
                instantiate(self._fmu, self._unzipped)
            else:
                self._fmu.reset()
            self._fmu.setupExperiment(startTime=0.0)
            self._fmu.enterInitializationMode()
            self._fmu.exitInitializationMode()
        except Exception as exc:  # noqa: BLE001 - FMPy's errors are plain Exceptions
            raise RunError(f"controller FMU {self.path}: cannot start ({exc})") from exc
        self._in_refs = list(self.inputs.values())
        self._in_names = list(self.inputs)
        self._out_refs = list(self.outputs.values())

    def step(self, values: Mapping[str, float], now: float) -> dict[str, float]:
        """One control cycle at ``now``: the inputs set, ``doStep(now, cycle)``, the outputs by DBC signal."""
        fmu = self._fmu
        try:
            set_values(fmu, self._in_refs, [values[name] for name in self._in_names])
            fmu.doStep(currentCommunicationPoint=now, communicationStepSize=self.cycle)
            return dict(zip(self.outputs, get_values(fmu, self._out_refs)))
        except Exception as exc:  # noqa: BLE001
            raise RunError(f"controller FMU {self.path}: step at t={now:g} s failed ({exc})") from exc

    def tcu_factory(self, db: Database, bus: can.BusABC, io: TcuIO | None = None) -> TcuRunner:
        """ecu-stub's bus side with this FMU as its controller (a ``RunConfig.tcu`` factory), on the matrix of
        ``io`` (the run's binding, :mod:`ecu_stub.tcu_io`: its messages, signals, units and the numbers of State
        and ActiveClutch, which the FMU then reads and writes too; None: the shipped DBC's)."""
        if io is None:
            codec = Codec(db, TCU_USES)
            self.tables = ValueTables()
        else:
            codec = io.codec(db)
            self.tables = ValueTables(states=io.state_values, clutches=io.clutch_values)
        command = "TCU_CMD" if io is None else io.names[2]
        self.cycle = codec.cycle_time(command)
        # TcuRunner is typed for CreepController; FmuController has the interface it uses (update, cal)
        return TcuRunner(codec, bus, controller=cast(CreepController, FmuController(self)), io=io)

    def close(self) -> None:
        if self._fmu is not None:
            try:
                self._fmu.terminate()
                self._fmu.freeInstance()
            except Exception:  # noqa: BLE001, S110 - closing: the run's own error, if any, is the one to show
                pass
            self._fmu = None
        shutil.rmtree(self._unzipped, ignore_errors=True)

    def __enter__(self) -> ControllerFmu:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class FmuController:
    """ecu-stub's controller interface (``update(inputs, now) -> TcuOutputs``) driving a :class:`ControllerFmu`.
    Building one (ecu-stub does at each lock-step start, as ``type(c)(c.cal)``) starts the FMU afresh."""

    def __init__(self, cal: ControllerFmu) -> None:
        self.cal = cal  # the name ecu-stub's runner rebuilds a controller from
        cal.start()

    def update(self, inputs: TcuInputs, now: float) -> TcuOutputs:
        fmu = self.cal
        values = fmu.step(input_values(inputs), now)
        try:
            return tcu_outputs(values, fmu.tables)
        except ValueError as exc:
            raise RunError(f"controller FMU {fmu.path}: {exc}") from exc


def open_controller(path: str | Path, mapping: str | Path | Mapping[str, str] | None = None) -> ControllerFmu:
    """A controller FMU checked and ready to run (``mapping``: a dict or a mapping file); see the module's
    docstring."""
    if mapping is not None and not isinstance(mapping, Mapping):
        mapping = load_mapping(mapping)
    return ControllerFmu(path, mapping)
