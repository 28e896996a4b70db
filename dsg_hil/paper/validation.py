"""Section III.C validation: the four 100-s rig cases beside the paper's published numbers."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ..physics.params import Params
from .reference import (RIG_CASES, RIG_DURATION_S, RIG_T_START_C, TOL_MU, TOL_RISE_C, TOL_TORQUE_REL,
                        RigReference)
from ..physics.rig import RigCase, RigTrace, run_rig

__all__ = ["CaseResult", "run_validation", "validation_json"]


@dataclass(frozen=True)
class CaseResult:
    reference: RigReference
    trace: RigTrace

    def as_json(self) -> dict:
        t = self.trace
        return {
            "case": self.reference.case,
            "pressure_mpa": self.reference.pressure_mpa,
            "speed_rpm": self.reference.speed_rpm,
            "temperature_rise_c": round(t.temperature_rise, 4),
            "torque_start_nm": round(float(t.torque[0]), 4),
            "torque_end_nm": round(float(t.torque[-1]), 4),
            "mu_start": round(float(t.mu[0]), 6),
            "mu_end": round(float(t.mu[-1]), 6),
        }

    def checks(self) -> list[tuple[str, float, float, float, bool]]:
        """(quantity, simulated, published, deviation, within the issue's band) for each published number."""
        r, t = self.reference, self.trace
        rows = [("temperature_rise_c", t.temperature_rise, r.temperature_rise_c,
                 t.temperature_rise - r.temperature_rise_c,
                 abs(t.temperature_rise - r.temperature_rise_c) <= TOL_RISE_C)]
        for name, sim, pub in (("torque_start_nm", t.torque[0], r.torque_start_nm),
                               ("torque_end_nm", t.torque[-1], r.torque_end_nm)):
            if pub is not None:
                rel = (sim - pub) / pub
                rows.append((name, float(sim), pub, rel, abs(rel) <= TOL_TORQUE_REL))
        for name, sim, pub in (("mu_start", t.mu[0], r.mu_start), ("mu_end", t.mu[-1], r.mu_end)):
            if pub is not None:
                rows.append((name, float(sim), pub, float(sim) - pub, abs(float(sim) - pub) <= TOL_MU + 1e-12))
        return rows


def run_validation(params: Params, dt: float = 1e-3,
                   progress: Callable[[str], None] | None = None) -> list[CaseResult]:
    """Run the four Section III.C cases (100 s, constant pressure and relative speed, from 40 degC)."""
    results = []
    for ref in RIG_CASES:
        if progress:
            progress(f"case {ref.case}: {ref.pressure_mpa} MPa, {ref.speed_rpm:g} r/min, {RIG_DURATION_S:g} s")
        trace = run_rig(params, RigCase(ref.pressure_mpa, ref.speed_rpm), RIG_DURATION_S, dt, RIG_T_START_C)
        results.append(CaseResult(ref, trace))
    return results


def validation_json(results: list[CaseResult]) -> dict:
    return {"cases": [r.as_json() for r in results]}
