"""Re-runnable calibrations of the parameters tagged ``calibrated`` in the parameter file.

* ``friction.A_stribeck``: the first term of (6), fitted with the unknown CH slip speed to Section V.B's
  mu_CH 0.063 -> 0.075 (T_CH 100 -> 250 degC) at the pressures that carry the creep load of Table I's vehicle at
  that slip (P = M_CH / (mu k_geom), about 0.78 -> 0.66 MPa; the paper prints 0.75 -> 0.65). Two equations, two
  unknowns; the slip fixes the default scenario's creep speed.
* ``thermal.clutch.test.h_plate_oil``: one parameter fitted by least squares to the four Section III.C rises after
  100 s (21 / 47 / 33 / 74 degC) on the rig configuration. Four targets, one unknown: the residuals test the model's
  structure, not its level. (Fitted to case 4 alone it leaves case 3 at -4.6 degC: the printed (6) makes mu fall
  with pressure, while the published rises imply it grows, so no single gain fits both pressures; see
  docs/explanation/fitted.md.)
* ``clutch.CL.C_plate``, ``clutch.CH.C_plate``, ``thermal.clutch.CL.Q_cool``, ``thermal.clutch.CH.Q_cool``: the
  vehicle's plate capacities and cooling flows, fitted by least squares to Section V.B's timeline (creep 174 s,
  slip CL 43.5 s / CH 130.5 s, CL at 205.5 degC when CH first reaches 250 degC, the on-coming CL at 246 degC at the
  stop) with the reduced model of :mod:`dsg_hil.paper.creep_model` on the default scenario. Five targets (174 s is the
  sum of the slips), four unknowns: zero residual degrees of freedom.
* ``powertrain.eta_*`` = 1 and ``clutch.{CL,CH}.N`` = 6: set by hand to bring P_CH nearest to Section V.B's.

``CALIBRATIONS`` states which published numbers (by the report's keys) each calibration consumes; the report's
"fitted"/"predicted" status of a number is derived from it (:func:`fitted_by`), and the fits read their published
values from the same ``Target`` tuples.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from .creep_model import CreepResult, creep_speed_for_slip, operating_point, simulate_creep
from ..common.units import CV
from ..physics.friction import friction_coefficient, torque_per_mu
from ..physics.params import Params
from .reference import (CREEP_MU_CH, CREEP_P_CH_MPA, CREEP_SLIP_TIME_S, CREEP_T_CL_AT_FIRST_CH_LIMIT_C,
                        CREEP_T_ONCOMING_AT_STOP_C, CREEP_T_START_C, CREEP_TIME_S, RIG_CASES, RIG_DURATION_S,
                        RIG_T_START_C,
                        SAFETY_TEMPERATURE_C, TOL_CREEP_MU, TOL_CREEP_P_MPA, TOL_CREEP_T_C, TOL_CREEP_TIME_REL,
                        TOL_SLIP_TIME_REL)
from ..physics.rig import RigCase, run_rig
from ..sim.scenario import Scenario, load_scenario

__all__ = ["CALIBRATIONS", "Calibration", "Check", "ETA_KEYS", "MU_TARGETS", "MU_TEMPERATURES_C",
           "PRESSURE_TARGETS", "RISE_KEYS", "SUMS", "StribeckFit", "TAKEOVER_MARGIN_C", "TIMELINE_TARGETS", "Target",
           "VEHICLE_THERMAL_KEYS",
           "calibrate_h_plate_oil", "calibrate_stribeck", "calibrate_vehicle_thermal", "fitted_by", "friction_checks",
           "reduced_creep", "rise_residuals", "timeline_checks", "timeline_residuals", "vehicle_thermal",
           "with_h_plate_oil", "with_vehicle_thermal"]


@dataclass(frozen=True)
class StribeckFit:
    A_stribeck: float
    slip_rpm: float  # CH slip speed of Section V.B's creep
    mu_start: float
    mu_end: float
    P_start_mpa: float  # the pressures that carry the creep load at mu_start, mu_end
    P_end_mpa: float


def calibrate_stribeck(params: Params) -> StribeckFit:
    """Fit A and the CH slip speed n so that mu(n, 100 degC, P_1) = 0.063 and mu(n, 250 degC, P_2) = 0.075, with
    P_i = M_CH / (mu_i k_geom) the pressure carrying the creep load at engine idle and the speed where CH slips n."""
    omega_e = params.engine.omega_idle
    k = torque_per_mu(params.clutch.CH, 1.0)
    points = [(T, t.published) for T, t in zip(MU_TEMPERATURES_C, MU_TARGETS)]

    def pressures(slip: float) -> list[float]:
        v = creep_speed_for_slip(params, omega_e, "CH", slip)
        M = operating_point(params, omega_e, v).torque["CH"]
        return [M / (mu * k) for _, mu in points]  # Pa

    def residual(x):  # x: A, n [r/min]
        f, slip = replace(params.friction, A_stribeck=x[0]), x[1] / CV.RAD_S_TO_RPM
        return [friction_coefficient(slip, T, P, f) - mu for (T, mu), P in zip(points, pressures(slip))]

    sol = least_squares(residual, x0=[0.03, 120.0], bounds=([0.0, 1.0], [1.0, 140.0]), xtol=1e-12, ftol=1e-12)
    A, n = float(sol.x[0]), float(sol.x[1])
    f = replace(params.friction, A_stribeck=A)
    P = pressures(n / CV.RAD_S_TO_RPM)
    mus = [friction_coefficient(n / CV.RAD_S_TO_RPM, T, P_i, f) for (T, _), P_i in zip(points, P)]
    return StribeckFit(A, n, mus[0], mus[1], P[0] / CV.MPA_TO_PA, P[1] / CV.MPA_TO_PA)


def with_h_plate_oil(params: Params, h: float) -> Params:
    """The parameters with the rig's test clutch h_plate_oil set to h."""
    cool = params.thermal.clutch
    return replace(params, thermal=replace(params.thermal,
                                           clutch=replace(cool, test=replace(cool.test, h_plate_oil=h))))


def rise_residuals(params: Params, dt: float = 1e-3) -> list[float]:
    """Simulated minus published temperature rise after 100 s for the four Section III.C cases [K]."""
    return [run_rig(params, RigCase(r.pressure_mpa, r.speed_rpm), RIG_DURATION_S, dt, RIG_T_START_C,
                    every=10**9).temperature_rise - r.temperature_rise_c for r in RIG_CASES]  # order of RISE_KEYS


def calibrate_h_plate_oil(params: Params, dt: float = 1e-3) -> float:
    """h [W/(m^2 K)] minimising the sum of squared rise residuals of the four Section III.C cases."""
    res = minimize_scalar(lambda h: sum(e * e for e in rise_residuals(with_h_plate_oil(params, h), dt)),
                          bounds=(500.0, 20000.0), method="bounded", options={"xatol": 1.0})
    return float(res.x)


# --- the vehicle's clutch thermal parameters against Section V.B ---------------------------------------------------

VEHICLE_THERMAL_KEYS = ("clutch.CL.C_plate", "clutch.CH.C_plate", "thermal.clutch.CL.Q_cool",
                        "thermal.clutch.CH.Q_cool")


def vehicle_thermal(params: Params) -> tuple[float, float, float, float]:
    """The four calibrated vehicle values, in the order of VEHICLE_THERMAL_KEYS."""
    c, t = params.clutch, params.thermal.clutch
    return c.CL.C_plate, c.CH.C_plate, t.CL.Q_cool, t.CH.Q_cool


def with_vehicle_thermal(params: Params, C_CL: float, C_CH: float, Q_CL: float, Q_CH: float) -> Params:
    c, t = params.clutch, params.thermal.clutch
    clutch = replace(c, CL=replace(c.CL, C_plate=C_CL), CH=replace(c.CH, C_plate=C_CH))
    cool = replace(t, CL=replace(t.CL, Q_cool=Q_CL), CH=replace(t.CH, Q_cool=Q_CH))
    return replace(params, clutch=clutch, thermal=replace(params.thermal, clutch=cool))


def reduced_creep(params: Params, scenario: Scenario | None = None, T_handover: float = SAFETY_TEMPERATURE_C,
                  T_takeover: float = SAFETY_TEMPERATURE_C - 10.0, dt: float = 0.05) -> CreepResult:
    """The reduced model of the scenario's creep (default: the shipped scenario): engine at its setpoint, the
    vehicle at the desired creep speed on the scenario's grade, plates and oil from the scenario's temperatures."""
    s = scenario or load_scenario()
    omega_e = params.engine.omega_idle if s.engine_speed_rpm is None else s.engine_speed_rpm / CV.RAD_S_TO_RPM
    v = max(d.desired_speed_mps for d in s.driver if d.creep_request)
    op = operating_point(params, omega_e, v, s.grade_rad)
    return simulate_creep(params, op, {"CL": s.T_CL_c, "CH": s.T_CH_c}, s.T_oil_c, T_handover, T_takeover, dt=dt)


@dataclass(frozen=True)
class Check:
    name: str  # the report's key of the published number (dsg_hil.paper.report.paper.PAPER)
    simulated: float
    published: float
    tolerance: float  # absolute

    @property
    def ok(self) -> bool:
        return abs(self.simulated - self.published) <= self.tolerance


@dataclass(frozen=True)
class Target:
    """A Section V.B number as the reduced model gives it: the report's key, the published value, its band
    (absolute) and how to read it off a :class:`CreepResult`."""

    key: str
    published: float
    tolerance: float
    simulated: Callable[[CreepResult], float]

    def check(self, r: CreepResult) -> Check:
        return Check(self.key, self.simulated(r), self.published, self.tolerance)


# Section V.B's timeline (Figs. 8-12) with its bands: the targets of calibrate_vehicle_thermal.
TIMELINE_TARGETS: tuple[Target, ...] = (
    Target("creep_time_s", CREEP_TIME_S, TOL_CREEP_TIME_REL * CREEP_TIME_S,
           lambda r: r.creep_time if r.stopped else float("inf")),
    Target("slip_time_s.CL", CREEP_SLIP_TIME_S["CL"], TOL_SLIP_TIME_REL * CREEP_SLIP_TIME_S["CL"],
           lambda r: r.slip_time["CL"]),
    Target("slip_time_s.CH", CREEP_SLIP_TIME_S["CH"], TOL_SLIP_TIME_REL * CREEP_SLIP_TIME_S["CH"],
           lambda r: r.slip_time["CH"]),
    Target("T_CL_at_first_CH_limit_c", CREEP_T_CL_AT_FIRST_CH_LIMIT_C, TOL_CREEP_T_C,
           lambda r: r.T_CL_at_first_CH_limit),
    Target("T_CL_at_stop_c", CREEP_T_ONCOMING_AT_STOP_C, TOL_CREEP_T_C, lambda r: r.T_oncoming_at_stop),
)
# Section V.B's first CH slip (Figs. 10, 11): mu_CH (the targets of calibrate_stribeck) and P_CH.
MU_TARGETS: tuple[Target, ...] = (
    Target("mu_CH_first_slip.start", CREEP_MU_CH[0], TOL_CREEP_MU, lambda r: r.mu_CH_first[0]),
    Target("mu_CH_first_slip.end", CREEP_MU_CH[1], TOL_CREEP_MU, lambda r: r.mu_CH_first[1]),
)
PRESSURE_TARGETS: tuple[Target, ...] = (
    Target("P_CH_first_slip_mpa.start", CREEP_P_CH_MPA[0], TOL_CREEP_P_MPA,
           lambda r: r.P_CH_first[0] / CV.MPA_TO_PA),
    Target("P_CH_first_slip_mpa.end", CREEP_P_CH_MPA[1], TOL_CREEP_P_MPA, lambda r: r.P_CH_first[1] / CV.MPA_TO_PA),
)
MU_TEMPERATURES_C = (CREEP_T_START_C, SAFETY_TEMPERATURE_C)  # T_CH at the start and end of the first CH slip
RISE_KEYS = tuple(f"cases.{r.case}.temperature_rise_c" for r in RIG_CASES)  # what rise_residuals compares, in order


def timeline_checks(r: CreepResult) -> list[Check]:
    """Section V.B's timeline: the simulated numbers beside the published ones, with their bands."""
    return [t.check(r) for t in TIMELINE_TARGETS]


def friction_checks(r: CreepResult) -> list[Check]:
    """Section V.B's first CH slip: mu_CH and P_CH at its start and end beside the published values."""
    return [t.check(r) for t in MU_TARGETS + PRESSURE_TARGETS]


TAKEOVER_MARGIN_C = 4.0  # the fit keeps CH this far below the take-over limit when CL's second slip ends


def timeline_residuals(r: CreepResult, T_takeover: float = SAFETY_TEMPERATURE_C - 10.0,
                       targets: tuple[Target, ...] | None = None) -> np.ndarray:
    """Band-scaled residuals of the timeline targets (default: TIMELINE_TARGETS), a penalty if the sequence is not
    the paper's CL, CH, CL, CH, stop, and one that keeps CH at least TAKEOVER_MARGIN_C below T_takeover when it
    takes over the second time (the paper's CH2 of ~10 s puts it near the limit; without a margin the closed loop
    stops one phase early)."""
    checks = [t.check(r) for t in (TIMELINE_TARGETS if targets is None else targets)]
    res = [(c.simulated - c.published) / c.tolerance if np.isfinite(c.simulated) else 3.0 for c in checks]
    sequence = [p.clutch for p in r.phases] + (["stop"] if r.stopped else [])
    res.append(0.0 if sequence == ["CL", "CH", "CL", "CH", "stop"] else 3.0)
    T_CH_takeover = r.phases[2].T_other_end if len(r.phases) > 2 else T_takeover
    res.append(max(0.0, T_CH_takeover - (T_takeover - TAKEOVER_MARGIN_C)))
    return np.array(res)


def calibrate_vehicle_thermal(params: Params, scenario: Scenario | None = None,
                              progress: Callable[[str], None] | None = None,
                              dt: float = 0.1) -> tuple[float, float, float, float]:
    """Least-squares fit of VEHICLE_THERMAL_KEYS to Section V.B's timeline (residuals scaled by their bands),
    from the parameter file's values, in log coordinates."""
    scenario = scenario or load_scenario()
    calls = [0]

    def residual(x):
        calls[0] += 1
        if progress and calls[0] % 10 == 0:
            progress(f"  {calls[0]} reduced-model runs ...")
        r = reduced_creep(with_vehicle_thermal(params, *np.exp(x)), scenario, dt=dt)
        return timeline_residuals(r, SAFETY_TEMPERATURE_C - 10.0)

    sol = least_squares(residual, np.log(vehicle_thermal(params)), diff_step=1e-2, xtol=1e-8)
    a, b, c, d = (float(v) for v in np.exp(sol.x))
    return a, b, c, d


# --- what is calibrated against what: the definition the report's "fitted"/"predicted" status is derived from ---

# published numbers that are a sum of others (174 s = 43.5 s + 130.5 s): they add no independent target
SUMS: dict[str, tuple[str, ...]] = {"creep_time_s": ("slip_time_s.CL", "slip_time_s.CH")}


@dataclass(frozen=True)
class Calibration:
    """One calibration: the quantities it sets (parameter keys as ``dsg-hil params`` lists them, or a scenario
    value in words) from the published numbers it consumes (``targets``: the report's keys)."""

    name: str
    quantities: tuple[str, ...]
    targets: tuple[str, ...]
    unknowns: int  # how many of the quantities are free in the fit (the rest move with them)
    how: str

    @property
    def independent_targets(self) -> int:
        return len(self.targets) - sum(k in self.targets and set(parts) <= set(self.targets)
                                       for k, parts in SUMS.items())

    @property
    def residual_dof(self) -> int:
        """Independent targets minus unknowns: 0 means any nearby published set would have been matched too."""
        return self.independent_targets - self.unknowns


ETA_KEYS = ("powertrain.eta_L", "powertrain.eta_H", "powertrain.eta_1", "powertrain.eta_b")

CALIBRATIONS: tuple[Calibration, ...] = (
    Calibration("stribeck", ("friction.A_stribeck", "scenario creep speed (CH slip)"),
                tuple(t.key for t in MU_TARGETS), 2, "calibrate_stribeck: two equations, two unknowns"),
    Calibration("pressure path", ETA_KEYS + ("clutch.CL.N", "clutch.CH.N"), tuple(t.key for t in PRESSURE_TARGETS),
                2, "by hand: N = 6 (a count) and eta = 1 (its bound) bring P_CH nearest"),
    Calibration("vehicle thermal", VEHICLE_THERMAL_KEYS, tuple(t.key for t in TIMELINE_TARGETS), 4,
                "calibrate_vehicle_thermal: least squares on the reduced model"),
    Calibration("rig heat transfer", ("thermal.clutch.test.h_plate_oil",), RISE_KEYS, 1,
                "calibrate_h_plate_oil: least squares on the rig"),
    Calibration("rig plate count", ("clutch.test.N",), ("cases.4.torque_start_nm",), 1,
                "the whole number nearest to torque / (mu P A_f r_m) of case 4 at 0 s"),
)


def fitted_by(key: str) -> Calibration | None:
    """The calibration that consumed the published number at ``key`` (a report key), or None: predicted."""
    return next((c for c in CALIBRATIONS if key in c.targets), None)
