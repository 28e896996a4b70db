"""The FMUs' units: one spelling each (the parameter file's; the DBC writes ``Nm``, ``m/s2``) and each one's
FMI 2.0 ``BaseUnit``, the SI base units' exponents with ``factor`` and ``offset`` (value in SI = factor * value +
offset), so an importer can convert and check connections."""

from __future__ import annotations

import math

__all__ = ["BASE_UNITS", "SPELLING", "fmi_unit"]

SPELLING = {"Nm": "N*m", "m/s2": "m/s^2", "-": "1", "": "1"}  # the DBC's spelling -> the FMUs'

# unit: ({base unit: exponent}, factor, offset)
BASE_UNITS: dict[str, tuple[dict[str, int], float, float]] = {
    "1": ({}, 1.0, 0.0),
    "%": ({}, 0.01, 0.0),
    "s": ({"s": 1}, 1.0, 0.0),
    "m": ({"m": 1}, 1.0, 0.0),
    "m^2": ({"m": 2}, 1.0, 0.0),
    "m^3": ({"m": 3}, 1.0, 0.0),
    "m^3/s": ({"m": 3, "s": -1}, 1.0, 0.0),
    "m/s": ({"m": 1, "s": -1}, 1.0, 0.0),
    "m/s^2": ({"m": 1, "s": -2}, 1.0, 0.0),
    "kg": ({"kg": 1}, 1.0, 0.0),
    "kg*m^2": ({"kg": 1, "m": 2}, 1.0, 0.0),
    "kg/m^3": ({"kg": 1, "m": -3}, 1.0, 0.0),
    "rad": ({"rad": 1}, 1.0, 0.0),
    "rad/s": ({"rad": 1, "s": -1}, 1.0, 0.0),
    "rpm": ({"rad": 1, "s": -1}, 2.0 * math.pi / 60.0, 0.0),
    "N*m": ({"kg": 1, "m": 2, "s": -2}, 1.0, 0.0),
    "N*m/rad": ({"kg": 1, "m": 2, "s": -2, "rad": -1}, 1.0, 0.0),
    "N*m*s/rad": ({"kg": 1, "m": 2, "s": -1, "rad": -1}, 1.0, 0.0),
    "Pa": ({"kg": 1, "m": -1, "s": -2}, 1.0, 0.0),
    "MPa": ({"kg": 1, "m": -1, "s": -2}, 1e6, 0.0),
    "W": ({"kg": 1, "m": 2, "s": -3}, 1.0, 0.0),
    "W/K": ({"kg": 1, "m": 2, "s": -3, "K": -1}, 1.0, 0.0),
    "W/(m^2*K)": ({"kg": 1, "s": -3, "K": -1}, 1.0, 0.0),
    "J/K": ({"kg": 1, "m": 2, "s": -2, "K": -1}, 1.0, 0.0),
    "J/(kg*K)": ({"m": 2, "s": -2, "K": -1}, 1.0, 0.0),
    "degC": ({"K": 1}, 1.0, 273.15),
}


def fmi_unit(unit: str | None) -> str:
    """The FMUs' spelling of a DBC or parameter-file unit."""
    return SPELLING.get(unit or "", unit or "1")
