"""The report's checks of the model itself: the hold-out of the Section V.B calibrations, the sensitivity table, and
the Table-I configuration beside the fitted one and the paper, with the reason for each difference."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from ...common.units import CV
from ...physics.params import Params, load_params
from ...sim.scenario import Scenario
from ..calibration import reduced_creep
from ..creep_model import CreepResult, operating_point
from ..holdout import BLOCKS, Block, HoldOut, hold_out
from ..sensitivity import Quantity, Sensitivity, VB_TARGETS, sensitivity
from .log import CreepRecord
from .paper import lookup

__all__ = ["ModelChecks", "TABLE1", "configuration_rows", "model_checks", "thermal_reason"]

TABLE1 = "table1"
L_PER_MIN = 6.0e4  # m^3/s -> L/min
TIMELINE_KEYS = ("creep_time_s", "slip_time_s.CL", "slip_time_s.CH", "T_CL_at_first_CH_limit_c", "T_CL_at_stop_c")


@dataclass(frozen=True)
class ModelChecks:
    holdout: list[HoldOut]
    sensitivity: Sensitivity
    reduced: dict[str, CreepResult]  # configuration ("given", TABLE1) -> the reduced model's creep
    table1: Params
    seconds: dict[str, float]  # wall time of each part

    def as_json(self) -> dict:
        return {"holdout": [h.as_json() for h in self.holdout], "sensitivity": self.sensitivity.as_json(),
                "wall_time_s": {k: round(v, 1) for k, v in self.seconds.items()}}


def model_checks(params: Params, scenario: Scenario, progress: Callable[[str], None] | None = None,
                 blocks: tuple[Block, ...] = BLOCKS, assumed: list[Quantity] | None = None) -> ModelChecks:
    """Hold-out, sensitivity and the reduced model of both configurations (seconds, timed)."""
    seconds = {}
    t0 = time.perf_counter()
    rows = hold_out(params, scenario, progress, blocks)
    seconds["holdout"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    table = sensitivity(params, scenario, progress, assumed)
    seconds["sensitivity"] = time.perf_counter() - t0
    table1 = load_params(TABLE1)
    reduced = {"given": reduced_creep(params, scenario), TABLE1: reduced_creep(table1, scenario)}
    return ModelChecks(rows, table, reduced, table1, seconds)


def _reduced_value(r: CreepResult, key: str) -> float | None:
    value = next(t.simulated(r) for t in VB_TARGETS if t.key == key)
    return float(value) if math.isfinite(value) else None


def _cooling(params: Params, clutch: str) -> tuple[float, float, float]:
    """(C_plate [J/K], cooling flow [L/min], its m_dot c_p [W/K])."""
    Q = getattr(params.thermal.clutch, clutch).Q_cool
    return (getattr(params.clutch, clutch).C_plate, Q * L_PER_MIN, Q * params.oil.rho * params.oil.c_p)


def thermal_reason(given: Params, table1: Params, scenario: Scenario, record: CreepRecord | None) -> str:
    """Why Table I's timeline differs: pack capacities and cooling flows of both configurations, where CL's creep
    heat would level off with Table I's flow, and what the loop did."""
    omega_e = given.engine.omega_idle if scenario.engine_speed_rpm is None else \
        scenario.engine_speed_rpm * CV.RPM_TO_RAD_S
    v = max(d.desired_speed_mps for d in scenario.driver if d.creep_request)
    heat = operating_point(table1, omega_e, v, scenario.grade_rad).heat["CL"]
    C, flow, G = _cooling(table1, "CL")
    fit = {c: _cooling(given, c) for c in ("CL", "CH")}
    text = (f"Table I packs: {C:.0f} J/K each, cooled by {flow:.1f} L/min (m_dot c_p {G:.0f} W/K); given "
            f"configuration: CL {fit['CL'][0]:.0f} J/K with {fit['CL'][1]:.2f} L/min ({fit['CL'][2]:.0f} W/K), CH "
            f"{fit['CH'][0]:.0f} J/K with {fit['CH'][1]:.1f} L/min ({fit['CH'][2]:.0f} W/K). CL's creep heat "
            f"{heat / CV.KW_TO_W:.1f} kW levels off near {scenario.T_oil_c + heat / G:.0f} °C with Table I's flow "
            f"(oil {scenario.T_oil_c:g} °C + heat / m_dot c_p)")
    if record is not None:
        m = record.metrics
        text += (f"; on the loop CL peaked at {m['max_plate_temp_c']['CL']} °C, CH at {m['max_plate_temp_c']['CH']} "
                 f"°C, slip time CL {m['slip_time_s']['CL']} s, CH {m['slip_time_s']['CH']} s, stop: "
                 f"{m['stop_reason']}")
    return text + "."


def _reason(key: str, t1: Params, metrics: dict | None, reduced: CreepResult) -> str:
    """The row's reason, short: the thermal explanation is given once (:func:`thermal_reason`)."""
    ch = metrics is not None and any(p["clutch"] == "CH" for p in metrics["phases"])
    stopped = metrics is not None and metrics["stop_time_s"] is not None
    if key in TIMELINE_KEYS:
        if not stopped and (metrics is not None or not reduced.stopped):
            return (f"no stop: CL never reaches 250 °C (its pack levels off below it with one "
                    f"{_cooling(t1, 'CL')[1]:.1f} L/min cooling flow), so no handover"
                    + ("" if key.startswith("slip_time") else ", and this number does not exist"))
        return "the packs' capacities and cooling flows (above)"
    if not ch and (metrics is not None or math.isnan(reduced.mu_CH_first[0])):
        return "CH never slips (no handover)"
    if key.startswith("mu_"):
        return ("(6) without its first term (A_stribeck = 0; only Section V.B's μ_CH could fix its amplitude): "
                "μ barely depends on T at the creep slip")
    return (f"P = M_CH / (μ N A_f r_m): the smaller μ of (6) without its first term, and η = "
            f"{t1.powertrain.eta_L:g} per mesh, need more pressure")


def configuration_rows(report: dict, table1_record: CreepRecord | None, checks: ModelChecks) -> list[dict]:
    """Section V.B's numbers: paper, the given configuration on the loop, Table I on the loop and on the reduced
    model, and the reason Table I differs."""
    metrics = None if table1_record is None else table1_record.metrics
    reduced = checks.reduced[TABLE1]
    return [{"key": t.key, "paper": t.published, "given_loop": lookup(report, t.key),
             "table1_loop": None if metrics is None else lookup(metrics, t.key),
             "table1_reduced": _reduced_value(reduced, t.key),
             "given_reduced": _reduced_value(checks.reduced["given"], t.key),
             "reason": _reason(t.key, checks.table1, metrics, reduced)} for t in VB_TARGETS]

