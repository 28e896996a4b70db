"""What both FMUs' slaves share: Real variables kept by name (PythonFMU's Fmi2Slave, its getters and setters on a
dict), a model description completed with units (:func:`complete_description`), and the balance of a reference
PythonFMU's binary releases (:func:`balance_namespace`)."""

from __future__ import annotations

import ctypes
from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

from .. import __version__
from .signals import Signal

__all__ = ["SignalSlave", "balance_namespace", "complete_description", "described"]


def complete_description(xml: Any, units: dict[str, str]) -> Any:
    """PythonFMU's model description ``xml`` completed: each Real variable named in ``units`` given its unit, the
    UnitDefinitions FMI 2.0 asks for (after the CoSimulation element, as the schema orders them), and the outputs
    listed as InitialUnknowns too (their values exist after initialization)."""
    from xml.etree.ElementTree import Element, SubElement  # noqa: PLC0415

    structure = xml.find("ModelStructure")
    outputs = structure.find("Outputs")
    if outputs is not None:
        initial = SubElement(structure, "InitialUnknowns")
        for unknown in outputs:
            SubElement(initial, "Unknown", {"index": unknown.get("index")})
    for variable in xml.iter("ScalarVariable"):
        unit = units.get(variable.get("name"))
        if unit is not None:
            variable.find("Real").set("unit", unit)
    definitions = Element("UnitDefinitions")
    for unit in sorted(set(units.values())):
        SubElement(definitions, "Unit", {"name": unit})
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


def described(signal: Signal) -> str:
    """A signal variable's description: its unit and where it is in the DBC."""
    return f"[{signal.unit}] DBC {signal.message}.{signal.signal}"


class SignalSlave(Fmi2Slave):
    """An Fmi2Slave whose variables are Reals with units, their values in ``self.values`` by name."""

    author = "dsg-hil developers"
    version = __version__

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.values: dict[str, float] = {}
        self.units: dict[str, str] = {}

    def real(self, name: str, start: float, unit: str, causality: Any, description: str) -> None:
        """Register a Real variable (a parameter: fixed, set before initialisation; else continuous)."""
        self.values[name] = start
        self.units[name] = unit
        variability = Fmi2Variability.fixed if causality == Fmi2Causality.parameter else Fmi2Variability.continuous
        self.register_variable(Real(name, causality=causality, variability=variability, description=description,
                                    getter=lambda: self.values[name],
                                    setter=lambda value: self.values.__setitem__(name, float(value))))

    def to_xml(self, model_options: dict[str, str] | None = None) -> Any:
        return complete_description(super().to_xml(model_options or {}), self.units)
