"""Hold-out check of the Section V.B calibrations: for each V.B number, re-fit its calibration without it and
predict it (leave-one-out on the reduced creep model the calibrations use, :func:`reduced_creep`).

Each calibration of :data:`dsg_hil.paper.calibration.CALIBRATIONS` that consumed V.B numbers is re-fitted alone
(the other calibrations' values as in the parameter file). With zero residual degrees of freedom, leaving a number
out can leave fewer independent targets than free quantities: then the free quantity the left-out number is most
sensitive to (among those with a prior) is fixed at its prior, the ``table1`` configuration's value (Table I and
stated assumptions, :data:`dsg_hil.physics.params.CONFIGURATIONS`), and the row says which. The clutches' N is a
count and stays as in the file.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..common.units import CV
from ..physics.params import Params, load_params
from ..sim.scenario import Scenario
from .calibration import (MU_TARGETS, PRESSURE_TARGETS, SUMS, TIMELINE_TARGETS, Target, reduced_creep,
                          timeline_residuals)
from .creep_model import CreepResult, creep_speed_for_slip
from .sensitivity import CALIBRATED, CREEP_SPEED, DT, VB_TARGETS, Quantity, elasticities

__all__ = ["BLOCKS", "Block", "HoldOut", "PRIOR_CONFIGURATION", "hold_out"]

PRIOR_CONFIGURATION = "table1"
ETA_MIN = 0.8
XTOL = 1e-4  # relative: the predictions need a few digits, not the calibration's 1e-8


@dataclass(frozen=True)
class Block:
    """A V.B calibration as the hold-out re-fits it: its free quantities (log coordinates where ``log``, else
    within ``bounds``, the calibration's own) and targets; ``sequence``: the timeline fit's penalties (CL, CH, CL,
    CH, stop; CH's take-over margin) apply."""

    calibration: str  # the name in CALIBRATIONS
    free: tuple[Quantity, ...]
    log: bool
    targets: tuple[Target, ...]
    bounds: Callable[[Params, Scenario], tuple[tuple[float, float], ...]] | None = None  # per free quantity
    sequence: bool = False


def _stribeck_bounds(params: Params, scenario: Scenario) -> tuple[tuple[float, float], ...]:
    """calibrate_stribeck's: A in [0, 1], the CH slip in [1, 140] r/min (as creep speeds)."""
    omega_e = params.engine.omega_idle if scenario.engine_speed_rpm is None else \
        scenario.engine_speed_rpm * CV.RPM_TO_RAD_S
    speed = [creep_speed_for_slip(params, omega_e, "CH", n * CV.RPM_TO_RAD_S) for n in (140.0, 1.0)]
    return (0.0, 1.0), (speed[0], speed[1])


def _quantities(*names: str) -> tuple[Quantity, ...]:
    by_name = {q.name: q for q in CALIBRATED}
    return tuple(by_name[n] for n in names)


BLOCKS: tuple[Block, ...] = (
    Block("stribeck", _quantities("friction.A_stribeck", CREEP_SPEED), False, MU_TARGETS, _stribeck_bounds),
    Block("pressure path", _quantities("powertrain.eta_* (4 meshes)"), False, PRESSURE_TARGETS,
          lambda p, s: ((ETA_MIN, 1.0),)),  # eta <= 1: the bound that is active in the file
    Block("vehicle thermal", _quantities("clutch.CL.C_plate", "clutch.CH.C_plate", "thermal.clutch.CL.Q_cool",
                                         "thermal.clutch.CH.Q_cool"), True, TIMELINE_TARGETS, sequence=True),
)


@dataclass(frozen=True)
class HoldOut:
    key: str
    calibration: str
    published: float
    tolerance: float
    predicted: float
    fixed: tuple[tuple[str, float], ...]  # (quantity, prior value) fixed because the rest cannot determine it
    refit: tuple[tuple[str, float], ...]  # the re-fitted free quantities

    @property
    def error(self) -> float:
        return self.predicted - self.published

    @property
    def ok(self) -> bool:
        return math.isfinite(self.predicted) and abs(self.error) <= self.tolerance

    def as_json(self) -> dict:
        return {"key": self.key, "calibration": self.calibration, "published": self.published,
                "band": self.tolerance, "predicted": _finite(self.predicted, 4),
                "error": _finite(self.error, 4), "within_band": self.ok,
                "fixed_at_prior": [{"quantity": q, "value": v} for q, v in self.fixed],
                "refit": [{"quantity": q, "value": v} for q, v in self.refit]}


def _finite(x: float, digits: int) -> float | None:
    return round(x, digits) if math.isfinite(x) else None


def _independent(targets: tuple[Target, ...]) -> int:
    keys = {t.key for t in targets}
    return len(keys) - sum(k in keys and set(parts) <= keys for k, parts in SUMS.items())


def _residuals(block: Block, targets: tuple[Target, ...], r: CreepResult) -> np.ndarray:
    if block.sequence:
        return timeline_residuals(r, targets=targets)
    return np.array([(t.simulated(r) - t.published) / t.tolerance if math.isfinite(t.simulated(r)) else 3.0
                     for t in targets])


def _leave_out(block: Block, left: Target, params: Params, scenario: Scenario, prior: tuple[Params, Scenario]
               ) -> HoldOut:
    remaining = tuple(t for t in block.targets if t is not left)
    free = list(block.free)
    fixed: list[tuple[str, float]] = []
    base_p, base_s = params, scenario
    if len(free) > _independent(remaining):
        ranked = sorted((q for q in free if q.keys),  # the creep speed has no prior
                        key=lambda q: -abs(_nan0(elasticities(params, scenario, q)[_vb_index(left)])))
        for q in ranked[:len(free) - _independent(remaining)]:
            value = q.get(*prior)
            base_p, base_s = q.set(base_p, base_s, value)
            fixed.append((q.name, value))
            free.remove(q)

    def apply(x: np.ndarray) -> tuple[Params, Scenario]:
        p, s = base_p, base_s
        for q, v in zip(free, np.exp(x) if block.log else x):
            p, s = q.set(p, s, float(v))
        return p, s

    x0 = np.array([q.get(base_p, base_s) for q in free])
    x0 = np.log(x0) if block.log else x0
    if free:
        kept = [i for i, q in enumerate(block.free) if q in free]
        lo, hi = (-np.inf, np.inf) if block.bounds is None else \
            np.array([block.bounds(params, scenario)[i] for i in kept]).T
        sol = least_squares(lambda x: _residuals(block, remaining, reduced_creep(*apply(x), dt=DT)),
                            np.clip(x0, lo, hi), bounds=(lo, hi), diff_step=1e-2 if block.log else 1e-4,
                            xtol=XTOL, ftol=XTOL)
        x = sol.x
    else:
        x = x0
    p, s = apply(x)
    predicted = left.simulated(reduced_creep(p, s, dt=DT))
    refit = tuple((q.name, float(v)) for q, v in zip(free, np.exp(x) if block.log else x))
    return HoldOut(left.key, block.calibration, left.published, left.tolerance, float(predicted), tuple(fixed), refit)


def _vb_index(target: Target) -> int:
    return [t.key for t in VB_TARGETS].index(target.key)


def _nan0(x: float) -> float:
    return 0.0 if math.isnan(x) else x


def hold_out(params: Params, scenario: Scenario, progress: Callable[[str], None] | None = None,
             blocks: tuple[Block, ...] = BLOCKS) -> list[HoldOut]:
    """Leave-one-out over every V.B number of every block (priors: the PRIOR_CONFIGURATION's values)."""
    prior = (load_params(PRIOR_CONFIGURATION), scenario)
    rows = []
    for block in blocks:
        for target in block.targets:
            if progress:
                progress(f"hold-out: {block.calibration} without {target.key} ...")
            rows.append(_leave_out(block, target, params, scenario, prior))
    return rows

