"""The documented operating range of the creep strategy, written once: every run checks its scenario and parameters
against it (:func:`outside_range`), and its summary says ``outside_range`` with each offending input; the sweep's
verdict says so too (``dsg_hil.sweep.verdict``), and the shipped safety space draws the whole range and
:attr:`Bound.margin` beyond it (tests/sim/test_operating_range.py).

A run outside the range still runs: the range is what the TCU is released for and what the safety claim covers, not
a limit of the simulation.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..common.units import CV
from ..physics.params import Params
from .scenario import Scenario

__all__ = ["OPERATING_RANGE", "Bound", "outside_range"]


@dataclass(frozen=True)
class Bound:
    """One input's range [lo, hi] (SI, temperatures degC) and the margin beyond it a safety space must also draw."""

    lo: float
    hi: float
    margin: float
    unit: str

    def contains(self, value: float) -> bool:
        return self.lo <= value <= self.hi


# name: the scenario's key (``initial.*``, ``driver.*``) or the parameter (``params.*``)
OPERATING_RANGE: dict[str, Bound] = {
    "grade_rad": Bound(-0.15, 0.25, 0.05, "rad"),  # downhill included; the TCU's launch.grade_max_rad is 0.25
    "params.vehicle.m": Bound(3920.0, 11760.0, 784.0, "kg"),  # Table I's 7,840 kg +-50 % (TCU: m_min/m_max_kg)
    "initial.T_CL_c": Bound(40.0, 150.0, 10.0, "degC"),
    "initial.T_CH_c": Bound(40.0, 150.0, 10.0, "degC"),
    "initial.T_oil_c": Bound(40.0, 150.0, 10.0, "degC"),
    "engine_speed_rpm": Bound(700.0, 2000.0, 100.0, "r/min"),
    "driver.desired_speed_mps": Bound(0.05, 0.4, 0.025, "m/s"),  # with creep requested (0: stand, held)
}


def _inputs(scenario: Scenario, params: Params) -> list[tuple[str, float]]:
    """The scenario's and parameters' values of each range input: the desired speed of every creep-requested
    driver event but a stand's (0: the TCU holds the vehicle), the grade and idle governor's setpoint of the
    parameters where the scenario gives none."""
    values = [("grade_rad", params.vehicle.beta if scenario.grade_rad is None else scenario.grade_rad),
              ("params.vehicle.m", params.vehicle.m), ("initial.T_CL_c", scenario.T_CL_c),
              ("initial.T_CH_c", scenario.T_CH_c), ("initial.T_oil_c", scenario.T_oil_c)]
    idle = params.engine.omega_idle * CV.RAD_S_TO_RPM if scenario.engine_speed_rpm is None else \
        scenario.engine_speed_rpm
    values.append(("engine_speed_rpm", idle))
    values += [("driver.desired_speed_mps", e.desired_speed_mps) for e in scenario.driver
               if e.creep_request and e.desired_speed_mps != 0.0]
    return values


def outside_range(scenario: Scenario, params: Params) -> list[str]:
    """Each input of the run outside :data:`OPERATING_RANGE`, once, as ``name=value (range lo..hi unit)``."""
    found: dict[str, str] = {}
    for name, value in _inputs(scenario, params):
        bound = OPERATING_RANGE[name]
        if name not in found and not bound.contains(value):
            found[name] = f"{name}={value:g} (range {bound.lo:g}..{bound.hi:g} {bound.unit})"
    return list(found.values())
