"""Which unknowns carry Section V.B: elasticities d ln(number) / d ln(quantity) of each V.B number, as the reduced
creep model (:func:`dsg_hil.paper.calibration.reduced_creep`) gives it, to each calibrated quantity and to each
assumed parameter that moves some number by at least :data:`INFLUENTIAL` (central differences, +-2 %).

A quantity is one value or a group set together (the four mesh efficiencies; both clutches' N; the scenario's creep
speed, which sets the CH slip). Temperatures enter in degC, as the paper prints them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import Any

from ..physics.params import Params
from ..sim.scenario import Scenario
from .calibration import (ETA_KEYS, MU_TARGETS, PRESSURE_TARGETS, TIMELINE_TARGETS, VEHICLE_THERMAL_KEYS, Target,
                          reduced_creep)

__all__ = ["CALIBRATED", "CREEP_SPEED", "INFLUENTIAL", "KNOWN", "Quantity", "STEP", "Sensitivity", "VB_TARGETS",
           "assumed_quantities", "elasticities", "sensitivity"]

VB_TARGETS: tuple[Target, ...] = TIMELINE_TARGETS + MU_TARGETS + PRESSURE_TARGETS
STEP = 0.02  # relative step of the central differences
INFLUENTIAL = 0.1  # an assumed parameter is shown when some |elasticity| reaches this
DT = 0.1  # s, the reduced model's step as the timeline calibration runs it
CREEP_SPEED = "scenario creep speed"


@dataclass(frozen=True)
class Quantity:
    """A value the V.B numbers depend on: parameter keys set together (``keys``), or the scenario's creep speed
    (``keys`` empty)."""

    name: str
    keys: tuple[str, ...] = ()

    def get(self, params: Params, scenario: Scenario) -> float:
        if not self.keys:
            return max(d.desired_speed_mps for d in scenario.driver if d.creep_request)
        return _get(params, self.keys[0])

    def set(self, params: Params, scenario: Scenario, value: float) -> tuple[Params, Scenario]:
        if not self.keys:
            driver = tuple(replace(d, desired_speed_mps=value) if d.creep_request else d for d in scenario.driver)
            return params, replace(scenario, driver=driver)
        for key in self.keys:
            params = _set(params, key.split("."), value)
        return params, scenario


def _get(obj: Any, key: str) -> float:
    for part in key.split("."):
        obj = getattr(obj, part)
    return float(obj)


def _set(obj: Any, path: list[str], value: float) -> Any:
    """``obj`` with the value at the dotted path replaced, unchecked (a finite difference may leave a range)."""
    inner = value if len(path) == 1 else _set(getattr(obj, path[0]), path[1:], value)
    return replace(obj, **{path[0]: inner})


CALIBRATED: tuple[Quantity, ...] = (
    Quantity("friction.A_stribeck", ("friction.A_stribeck",)),
    Quantity(CREEP_SPEED),
    Quantity("powertrain.eta_* (4 meshes)", ETA_KEYS),
    Quantity("clutch.CL/CH.N", ("clutch.CL.N", "clutch.CH.N")),
    *(Quantity(key, (key,)) for key in VEHICLE_THERMAL_KEYS),
)


KNOWN = ("vehicle.g",)  # tagged assumed, but not an unknown (standard gravity)


def assumed_quantities(params: Params) -> list[Quantity]:
    """Every parameter tagged ``assumed`` with a non-zero value, one quantity each (N is in CALIBRATED), but KNOWN."""
    grouped = {k for q in CALIBRATED for k in q.keys}
    return [Quantity(key, (key,)) for key, (source, _) in params.provenance.items()
            if source == "assumed" and key not in grouped and key not in KNOWN and _get(params, key) != 0.0]


def _numbers(params: Params, scenario: Scenario | None) -> list[float]:
    r = reduced_creep(params, scenario, dt=DT)
    return [t.simulated(r) for t in VB_TARGETS]


def elasticities(params: Params, scenario: Scenario, quantity: Quantity,
                 base: list[float] | None = None) -> list[float]:
    """d ln(number) / d ln(quantity) of each of VB_TARGETS, central; forward from ``base`` (the numbers at the
    point, one run instead of two) if given. NaN where a side loses the number (no stop, no CH slip) or the
    quantity is zero."""
    value = quantity.get(params, scenario)
    if value == 0.0:
        return [math.nan] * len(VB_TARGETS)
    steps = (STEP,) if base is not None else (STEP, -STEP)
    sides = [_numbers(*quantity.set(params, scenario, value * (1.0 + s))) for s in steps]
    if base is not None:
        sides.append(base)
    span = math.log((1.0 + STEP) / (1.0 - STEP)) if base is None else math.log(1.0 + STEP)
    return [(math.log(a) - math.log(b)) / span if a > 0 and b > 0 and math.isfinite(a) and math.isfinite(b)
            else math.nan for a, b in zip(*sides)]


@dataclass(frozen=True)
class Sensitivity:
    numbers: tuple[str, ...]  # report keys of the V.B numbers (rows)
    quantities: tuple[str, ...]  # columns
    calibrated: tuple[bool, ...]  # per column: a calibrated quantity (else an assumed one)
    elasticity: tuple[tuple[float, ...], ...]  # [row][column]
    screened: int  # assumed parameters tried

    def as_json(self) -> dict:
        return {"numbers": list(self.numbers), "quantities": list(self.quantities),
                "calibrated": list(self.calibrated), "screened_assumed": self.screened, "step": STEP,
                "elasticity": [[None if math.isnan(e) else round(e, 3) for e in row] for row in self.elasticity]}

    def top(self, n: int = 10) -> list[tuple[str, str, float]]:
        """The n largest |elasticities|: (number, quantity, elasticity)."""
        cells = [(self.numbers[i], self.quantities[j], e) for i, row in enumerate(self.elasticity)
                 for j, e in enumerate(row) if not math.isnan(e)]
        return sorted(cells, key=lambda c: -abs(c[2]))[:n]


def sensitivity(params: Params, scenario: Scenario, progress: Callable[[str], None] | None = None,
                assumed: Iterable[Quantity] | None = None) -> Sensitivity:
    """The elasticity table: every calibrated quantity, and the assumed parameters (default: all of them,
    screened) whose largest |elasticity| reaches INFLUENTIAL."""
    candidates = list(assumed) if assumed is not None else assumed_quantities(params)
    if progress:
        progress(f"sensitivity: {len(CALIBRATED)} calibrated quantities, {len(candidates)} assumed parameters "
                 "screened (forward differences), the influential ones by central differences ...")
    columns: list[tuple[Quantity, list[float], bool]] = [(q, elasticities(params, scenario, q), True)
                                                        for q in CALIBRATED]
    base = _numbers(params, scenario)
    for q in candidates:
        e = elasticities(params, scenario, q, base)
        if any(abs(x) >= INFLUENTIAL for x in e if not math.isnan(x)):
            columns.append((q, elasticities(params, scenario, q), False))
    rows = tuple(tuple(col[1][i] for col in columns) for i in range(len(VB_TARGETS)))
    return Sensitivity(tuple(t.key for t in VB_TARGETS), tuple(q.name for q, _, _ in columns),
                       tuple(c for _, _, c in columns), rows, len(candidates))

