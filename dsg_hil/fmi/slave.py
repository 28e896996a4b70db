"""What both FMUs' slaves share: Real variables kept by name (PythonFMU's Fmi2Slave, its getters and setters on a
dict), a model description completed with units, ranges and dependencies (:func:`complete_description`), the
calls of a host checked (:class:`SignalSlave`), the variable list's digest (:func:`variables_digest`), the
balance of a reference PythonFMU's binary releases (:func:`balance_namespace`) and the end of the binary's state
at the host's exit (:func:`dsg_hil.fmi.host.end_binary_state_at_exit`).

A caller's mistake never leaves the slave as a Python exception: PythonFMU's binary (0.6.4 to 0.7.0, ``handle_py_
exception``) turns any into ``fmi2Fatal`` and frees the Python object, so the instance's next call crashes the
host. The slave logs it instead (status ``fmi2Error``, the call and the value named), leaves the value as it was,
and discards the next ``fmi2DoStep`` (``fmi2Discard``, the one status the binary lets a slave return besides
``fmi2OK``). The refused call itself returns ``fmi2Error`` through dsg-hil's shim, the FMU's linux64 binary
(``dsg_hil/fmi/shim.c``, :mod:`dsg_hil.fmi.export`), which returns ``fmi2Error`` for a call during which an
``fmi2Error`` message was logged. PythonFMU's binary alone (win64; linux64 where the export had no C compiler)
returns ``fmi2OK`` for it: its ``fmi2.cpp`` (0.7.0 and git main) returns ``fmi2Error`` only for a C++ exception
other than the ``fmi2Fatal`` one it makes of every Python exception, which no Python code can raise. There the
refusal shows at the next step."""

from __future__ import annotations

import ctypes
import hashlib
import json
import math
import uuid
from collections.abc import Iterable
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

from .. import __version__
from ..common.errors import InputError
from .host import end_binary_state_at_exit
from .signals import Signal
from .units import BASE_UNITS, fmi_unit

__all__ = ["FmuCallError", "SignalSlave", "balance_namespace", "complete_description", "described", "guid_of",
           "variables_digest"]

_TYPES: dict[str, tuple[Any, Any]] = {"Real": (Real, float), "Integer": (Integer, int), "Boolean": (Boolean, bool)}
_ROUNDING = 1e-9  # of an input's range: a value beyond a bound by this much is taken as the bound
_GUID_NAMESPACE = uuid.UUID("5b0f6c1e-3f1d-4f35-9d0e-7a1c2f4b8e61")  # dsg-hil's FMUs (uuid5 of model and digest)


class FmuCallError(InputError):
    """A call of an FMI host the FMU refuses (an unknown value reference, a value out of range, a step it cannot
    take, a call in the wrong state), or a host whose dsg-hil does not register the FMU's variables."""


def complete_description(xml: Any, units: dict[str, str],
                         limits: dict[str, tuple[float, float]] | None = None) -> Any:
    """PythonFMU's model description ``xml`` completed: each Real variable named in ``units`` given its unit (and
    its ``min``/``max`` where ``limits`` names it), the UnitDefinitions FMI 2.0 asks for (after the CoSimulation
    element, as the schema orders them), the outputs listed as InitialUnknowns too (their values exist after
    initialization), and each output's dependencies: none, since an output changes only in ``fmi2DoStep`` (no
    direct feedthrough; without the attribute FMI 2.0 reads "depends on every input")."""
    from xml.etree.ElementTree import Element, SubElement  # noqa: PLC0415

    structure = xml.find("ModelStructure")
    outputs = structure.find("Outputs")
    if outputs is not None:
        initial = SubElement(structure, "InitialUnknowns")
        for unknown in outputs:
            unknown.set("dependencies", "")
            SubElement(initial, "Unknown", {"index": unknown.get("index")})
    for variable in xml.iter("ScalarVariable"):
        typed = variable[0]  # the Real, Integer or Boolean element
        unit = units.get(variable.get("name"))
        if unit is not None:
            typed.set("unit", unit)
        low_high = (limits or {}).get(variable.get("name"))
        if low_high is not None:
            low, high = low_high
            typed.set("min", repr(low) if typed.tag == "Real" else str(int(low)))
            typed.set("max", repr(high) if typed.tag == "Real" else str(int(high)))
    definitions = Element("UnitDefinitions")
    for unit in sorted(set(units.values())):
        element = SubElement(definitions, "Unit", {"name": unit})
        if unit in BASE_UNITS:
            exponents, factor, offset = BASE_UNITS[unit]
            SubElement(element, "BaseUnit", {**{name: str(power) for name, power in exponents.items()},
                                             "factor": repr(factor), "offset": repr(offset)})
    xml.insert(list(xml).index(xml.find("CoSimulation")) + 1, definitions)
    return xml


def balance_namespace(namespace: dict[str, Any], local: dict[str, Any]) -> None:
    """Give an FMU's slave module's ``namespace`` (its ``globals()``) back the reference PythonFMU's binary takes
    from it: called at the module's top level with ``globals(), locals()``.

    The binary (since PythonFMU 0.6.4, checked up to 0.7.0: ``findClass`` in ``PySlaveInstance.cpp``) finds the
    slave class by running the module's source once more in the module's namespace, with a ``locals`` of its own,
    then releases the namespace (``Py_DECREF`` of ``PyModule_GetDict``'s borrowed reference), a reference it never
    took. One short, per instance, so that at the host's shutdown the namespace is freed while its module still
    holds it ("corrupted double-linked list", a segmentation fault). That run is the only one with ``locals``
    apart from ``globals`` (an import runs a module in its namespace), so one reference more there is exactly
    what it takes; ``tests/fmi/test_namespace.py`` counts them."""
    if local is not namespace:
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(namespace))


def variables_digest(variables: Iterable[Any]) -> str:
    """A digest of an FMU's variable list (value reference, name, type, causality, variability, in order): what a
    host's dsg-hil must register for the FMU's value references to mean what its description says."""
    rows = [[v.value_reference, v.name, type(v).__name__, str(v.causality), str(v.variability)] for v in variables]
    return hashlib.sha256(json.dumps(rows).encode("utf-8")).hexdigest()[:16]


def guid_of(model: str, digest: str) -> str:
    """The GUID of a dsg-hil FMU: a name-based UUID of the model and its variable digest."""
    return str(uuid.uuid5(_GUID_NAMESPACE, f"dsg-hil {model} {digest}"))


def described(signal: Signal) -> str:
    """A signal variable's description: its unit and where it is in the DBC."""
    return f"[{signal.unit}] DBC {signal.message}.{signal.signal}"


def _limits(signal: Signal) -> tuple[float, float] | None:
    if signal.minimum is None or signal.maximum is None:
        return None
    return signal.minimum, signal.maximum


class SignalSlave(Fmi2Slave):
    """An Fmi2Slave whose variables are Reals with units, their values in ``self.values`` by name, every host call
    checked (module docstring). A subclass registers its variables, then calls :meth:`seal`; it implements
    :meth:`initialise`, :meth:`step` and, for an FMU state, :meth:`snapshot` / :meth:`restore`."""

    author = "dsg-hil developers"
    model = ""  # the model's name (export.MODELS)
    # (dsg-hil version, variables_digest) the FMU was written with: set by the module 'dsg-hil fmu export' writes
    exported: tuple[str, str] | None = None

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.version = __version__
        self.values: dict[str, float] = {}
        self.units: dict[str, str] = {}
        self.kinds: dict[str, str] = {}
        self.limits: dict[str, tuple[float, float]] = {}
        self.causalities: dict[str, Any] = {}
        self.phase = "instantiated"  # -> initialising -> initialised -> terminated
        self.time: float | None = None  # where the last step ended (None: no step yet)
        self.refused: str | None = None  # the last refused call: the next doStep is discarded
        self.digest = ""
        if self.resources:  # instantiated by PythonFMU's binary (not by 'dsg-hil fmu export', which passes None)
            end_binary_state_at_exit(Path(self.resources).parent)

    def real(self, name: str, start: float, unit: str, causality: Any, description: str,
             limits: tuple[float, float] | None = None, kind: str = "Real") -> None:
        """Register a variable (a Real, or an Integer or Boolean ``kind``; a parameter: fixed, set before
        initialisation; else continuous, or discrete where not a Real), its value in ``self.values``."""
        self.values[name] = start
        self.kinds[name] = kind
        if kind == "Real":
            self.units[name] = fmi_unit(unit)
        self.causalities[name] = causality
        if limits is not None and kind != "Boolean":
            self.limits[name] = limits
        variability = (Fmi2Variability.fixed if causality == Fmi2Causality.parameter else
                       Fmi2Variability.continuous if kind == "Real" else Fmi2Variability.discrete)
        cls, read = _TYPES[kind]
        self.register_variable(cls(name, causality=causality, variability=variability, description=description,
                                   getter=lambda: read(self.values[name]),
                                   setter=lambda value: self.values.__setitem__(name, float(value))))

    def signal(self, signal: Signal, causality: Any, start: float = 0.0, description: str | None = None) -> None:
        """Register a DBC signal's variable (an input's range: the DBC's)."""
        self.real(signal.name, start, signal.unit, causality, description or described(signal),
                  _limits(signal) if causality == Fmi2Causality.input else None, signal.kind)

    def seal(self) -> None:
        """After the variables are registered: the digest and the GUID of them; on a host whose dsg-hil registers
        other variables than the FMU was written with (:attr:`exported`), or whose GUID is not the description's,
        an FmuCallError naming both versions (instantiation fails)."""
        self.digest = variables_digest(self.vars.values())
        self.guid = guid_of(self.model, self.digest)
        if self.exported is not None and self.exported[1] != self.digest:
            raise FmuCallError(f"fmi2Instantiate: this FMU was written by dsg-hil {self.exported[0]} (variables "
                               f"{self.exported[1]}); the host's dsg-hil {__version__} registers other variables "
                               f"({self.digest}): export it again with the host's dsg-hil, or install "
                               f"dsg-hil=={self.exported[0]} there")
        described_guid = self._description_guid()
        if described_guid is not None and described_guid != self.guid:
            raise FmuCallError(f"fmi2Instantiate: the FMU's modelDescription.xml has the GUID {described_guid}, the "
                               f"host's dsg-hil {__version__} gives {self.guid} for its variables (FMU written by "
                               f"dsg-hil {self.exported[0] if self.exported else 'unknown'})")

    def _description_guid(self) -> str | None:
        """The GUID of the FMU's modelDescription.xml (beside its resources), None where there is none."""
        if not self.resources:
            return None
        path = Path(self.resources).parent / "modelDescription.xml"
        if not path.is_file():
            return None
        return ElementTree.parse(path).getroot().get("guid")

    # ---- what a subclass implements ---------------------------------------------------------------------------
    def initialise(self) -> None:
        """exitInitializationMode's work (raise FmuCallError for a bad parameter)."""

    def step(self, current_time: float, step_size: float) -> None:
        """doStep's work (raise FmuCallError for a step the model cannot take)."""

    def snapshot(self) -> dict[str, Any]:
        """What an FMU state holds besides the variables (JSON-able)."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Back to a :meth:`snapshot` (the variables restored already)."""

    # ---- the host's calls, checked ----------------------------------------------------------------------------
    def refuse(self, call: str, why: object) -> None:
        """Log a refused call (fmi2Error) and discard the next step."""
        message = f"{call}: {why}"
        self.log(message, Fmi2Status.error)
        self.refused = message

    def setup_experiment(self, start_time: float, stop_time: float | None = None,
                         tolerance: float | None = None) -> None:
        if self.phase != "instantiated":
            self.refuse("fmi2SetupExperiment", f"start time {start_time}: only before initialization")
        elif not math.isfinite(start_time):
            self.refuse("fmi2SetupExperiment", f"start time {start_time}: not a finite time")
        else:
            self.time = start_time

    def enter_initialization_mode(self) -> None:
        if self.phase != "instantiated":
            self.refuse("fmi2EnterInitializationMode", f"the FMU is {self.phase}")
        else:
            self.phase = "initialising"

    def exit_initialization_mode(self) -> None:
        if self.phase != "initialising":
            self.refuse("fmi2ExitInitializationMode", f"the FMU is {self.phase}, not in initialization mode")
            return
        try:
            self.initialise()
        except Exception as exc:  # noqa: BLE001 - never into PythonFMU's binary (module docstring)
            self.refuse("fmi2ExitInitializationMode", f"{exc}; the FMU stays uninitialised")
            self.phase = "instantiated"
            return
        self.phase = "initialised"

    def do_step(self, current_time: float, step_size: float) -> bool:
        call = f"fmi2DoStep(t={current_time!r}, h={step_size!r})"
        why = self._cannot_step(current_time, step_size)
        if why is None:
            try:
                self.step(current_time, step_size)
            except Exception as exc:  # noqa: BLE001 - never into PythonFMU's binary
                why = str(exc)
        if why is not None:  # this step is discarded: the refusal ends here
            self.log(f"{call}: {why}", Fmi2Status.error)
            self.refused = None
            return False
        self.time = current_time + step_size
        return True

    def _cannot_step(self, current_time: float, step_size: float) -> str | None:
        """Why a step cannot be taken (None: it can)."""
        if self.refused is not None:
            return f"discarded: a call before it was refused ({self.refused})"
        if self.phase != "initialised":
            return f"the FMU is {self.phase}" + (": call fmi2ExitInitializationMode first"
                                                 if self.phase != "terminated" else "")
        if not (math.isfinite(current_time) and math.isfinite(step_size)) or step_size < 0.0:
            return "the time and the step must be finite, the step not negative"
        if self.time is not None and abs(current_time - self.time) > 1e-9 * max(1.0, abs(self.time)):
            return (f"the last step ended at t={self.time!r}: a step starts there (or, after fmi2SetFMUstate, at "
                    f"the state's time)")
        return None

    def terminate(self) -> None:
        self.phase = "terminated"

    def _variable(self, vr: int, kind: str) -> Any:
        variable = self.vars.get(vr)
        if variable is None:
            raise FmuCallError(f"value reference {vr}: no such variable")
        if type(variable).__name__ != kind:
            raise FmuCallError(f"value reference {vr} ({variable.name}) is a {type(variable).__name__}, not "
                               f"a{'n' if kind == 'Integer' else ''} {kind}")
        return variable

    def _set(self, name: str, value: float) -> None:
        causality = self.causalities[name]
        if causality == Fmi2Causality.output:
            raise FmuCallError(f"{name} is an output: the FMU sets it")
        if causality == Fmi2Causality.parameter and self.phase not in ("instantiated", "initialising"):
            raise FmuCallError(f"{name} = {value!r}: a fixed parameter, set before fmi2ExitInitializationMode")
        if not math.isfinite(value):
            raise FmuCallError(f"{name} = {value!r}: not a finite number")
        low_high = self.limits.get(name)
        if low_high is not None:
            low, high = low_high
            rounding = _ROUNDING * max(1.0, high - low)  # a master's interpolation may miss a bound by an ulp
            if not low - rounding <= value <= high + rounding:
                raise FmuCallError(f"{name} = {value!r}: out of the DBC's range [{low:g}, {high:g}] "
                                   f"{self.units[name]}")
            value = min(max(value, low), high)
        self.values[name] = float(value)

    def _set_all(self, call: str, kind: str, vrs: list[int], values: list[float]) -> None:
        """Set each variable (of FMI type ``kind``) a host's call names; a refused one logged, the rest set."""
        for vr, value in zip(vrs, values):
            try:
                self._set(self._variable(vr, kind).name, value)
            except Exception as exc:  # noqa: BLE001 - never into PythonFMU's binary
                self.refuse(call, f"{exc}; not set")

    def _get_all(self, call: str, kind: str, vrs: list[int], instead: Any) -> list[Any]:
        """The values of the variables a host's call names (``instead`` for one that cannot be read, logged)."""
        got = []
        for vr in vrs:
            try:
                got.append(self._variable(vr, kind).getter())
            except Exception as exc:  # noqa: BLE001 - never into PythonFMU's binary
                self.refuse(call, f"{exc}; {instead!r} returned")
                got.append(instead)
        return got

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        self._set_all("fmi2SetReal", "Real", vrs, [float(v) for v in values])

    def get_real(self, vrs: list[int]) -> list[float]:
        return [float(v) for v in self._get_all("fmi2GetReal", "Real", vrs, math.nan)]

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        self._set_all("fmi2SetInteger", "Integer", vrs, [float(v) for v in values])

    def get_integer(self, vrs: list[int]) -> list[int]:
        return [int(v) for v in self._get_all("fmi2GetInteger", "Integer", vrs, 0)]

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        self._set_all("fmi2SetBoolean", "Boolean", vrs, [1.0 if v else 0.0 for v in values])

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        return [bool(v) for v in self._get_all("fmi2GetBoolean", "Boolean", vrs, False)]

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        for vr in vrs:
            try:
                self._variable(vr, "String")
            except FmuCallError as exc:
                self.refuse("fmi2SetString", f"{exc}; not set")

    def get_string(self, vrs: list[int]) -> list[str]:
        for vr in vrs:
            try:
                self._variable(vr, "String")
            except FmuCallError as exc:
                self.refuse("fmi2GetString", f"{exc}; an empty string returned")
        return [""] * len(vrs)

    # ---- FMU state: the variables, the phase, the time and the subclass's snapshot ----------------------------
    def _get_fmu_state(self) -> dict[str, Any]:
        try:
            return {"values": dict(self.values), "phase": self.phase, "time": self.time, "model": self.snapshot()}
        except Exception as exc:  # noqa: BLE001
            self.refuse("fmi2GetFMUstate", exc)
            return {"error": f"fmi2GetFMUstate: {exc}"}

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        try:
            if "error" in state:
                raise FmuCallError(f"not a state ({state['error']})")
            if set(state["values"]) != set(self.values):
                raise FmuCallError("a state of another FMU (other variables)")
            self.values.update(state["values"])
            self.phase, self.time = state["phase"], state["time"]
            self.restore(state["model"])
        except Exception as exc:  # noqa: BLE001
            self.refuse("fmi2SetFMUstate", exc)

    @staticmethod
    def _fmu_state_to_bytes(state: dict[str, Any]) -> bytes:
        return json.dumps(state).encode("utf-8")  # floats as repr: the same double back

    @staticmethod
    def _fmu_state_from_bytes(state: bytes) -> dict[str, Any]:
        try:
            loaded = json.loads(state.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as exc:
            return {"error": f"fmi2DeSerializeFMUstate: not a serialised state of this FMU ({exc})"}
        return loaded if isinstance(loaded, dict) else {"error": "fmi2DeSerializeFMUstate: not a state"}

    def to_xml(self, model_options: dict[str, str] | None = None) -> Any:
        return complete_description(super().to_xml(model_options or {}), self.units, self.limits)
