"""Reduced model of the Section V.B creep: the plant's thermal network driven by the quasi-static heat of the
paper's idealised strategy. Used to calibrate the vehicle's clutch thermal parameters in seconds.

Quasi-static: the vehicle creeps at constant speed v on the grade, the engine turns at its setpoint, so the slipping
clutch carries the road load (13) reflected through its path ((10)-(12) at rest: M_k = M_R / (i_b eta_b i_1 eta_1
i_k eta_k)) at the slip the speeds impose; its friction heat (4) M_k * slip_k is constant whatever mu does (the
speed controller trims the pressure to hold the torque: P_k = M_k / (mu k_geom), with mu from (6) at that slip,
the plate temperature and P_k itself).

Idealised strategy (Section V.A/B): CL slips first; when the slipping clutch reaches ``T_handover`` the other one
takes over if it is below ``T_takeover``, otherwise the vehicle stops. The handover is instantaneous.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..common.units import CV
from ..physics.friction import friction_coefficient, torque_per_mu
from ..physics.params import Params
from ..physics.powertrain import road_load
from ..physics.thermal import NODES, discretize, gearbox_network, heat_sources
from ..physics.plant import Plant, PlantInputs
from ..sim.scenario import Scenario

__all__ = ["CLUTCHES", "CreepResult", "OperatingPoint", "Phase", "creep_speed_for_slip", "operating_point",
           "pressure_for_torque", "run_plant_creep", "simulate_creep"]

CLUTCHES = ("CL", "CH")


@dataclass(frozen=True)
class OperatingPoint:
    """Steady creep at engine speed omega_e [rad/s] and vehicle speed v [m/s] on a grade [rad]."""

    omega_e: float
    v: float
    grade: float
    slip: dict[str, float]  # rad/s
    torque: dict[str, float]  # N m the slipping clutch carries
    heat: dict[str, float]  # W, friction heat (4) while that clutch alone slips


def operating_point(params: Params, omega_e: float, v: float, grade: float | None = None) -> OperatingPoint:
    """Slip, torque and heat of each clutch if it alone drives the vehicle at v (quasi-static (7)-(13))."""
    pt, veh = params.powertrain, params.vehicle
    grade = veh.beta if grade is None else grade
    M_fixed, M_resist = road_load(v, grade, 0.0, veh)
    M_wheel = M_fixed + M_resist  # moving uphill: rolling resistance opposes motion
    omega_1 = omega_e / pt.i_a
    omega_4 = v / veh.r_w * pt.i_b * pt.i_1
    slip, torque, heat = {}, {}, {}
    for k, (i_k, eta_k) in {"CL": (pt.i_L, pt.eta_L), "CH": (pt.i_H, pt.eta_H)}.items():
        slip[k] = omega_1 - omega_4 * i_k
        torque[k] = M_wheel / (pt.i_b * pt.eta_b * pt.i_1 * pt.eta_1 * i_k * eta_k)
        heat[k] = torque[k] * slip[k]
    return OperatingPoint(omega_e, v, grade, slip, torque, heat)


def creep_speed_for_slip(params: Params, omega_e: float, clutch: str, slip: float) -> float:
    """Vehicle speed [m/s] at which ``clutch`` slips ``slip`` [rad/s] with the engine at omega_e [rad/s]."""
    pt, veh = params.powertrain, params.vehicle
    i_k = pt.i_L if clutch == "CL" else pt.i_H
    return (omega_e / pt.i_a - slip) / i_k / (pt.i_1 * pt.i_b) * veh.r_w


def pressure_for_torque(params: Params, clutch: str, torque: float, slip: float, T_c: float) -> tuple[float, float]:
    """(P [Pa], mu) with mu(slip, T, P) k_geom P = torque (slip [rad/s]): (5)-(6) solved by fixed-point iteration."""
    k = torque_per_mu(getattr(params.clutch, clutch), 1.0)
    P = torque / (0.065 * k)
    for _ in range(50):
        mu = friction_coefficient(slip, T_c, P, params.friction)
        P_new = torque / (mu * k)
        if abs(P_new - P) < 1e-3:
            break
        P = P_new
    return P_new, mu


@dataclass
class Phase:
    clutch: str
    t_start: float
    t_end: float = math.nan
    T_other_end: float = math.nan  # the other clutch's plate temperature when this phase ends


@dataclass
class CreepResult:
    phases: list[Phase]
    creep_time: float  # s, until the stop (or the end of the horizon)
    stopped: bool
    slip_time: dict[str, float]
    T_max: dict[str, float]
    mu_CH_first: tuple[float, float] = (math.nan, math.nan)  # start, end of the first CH slip
    P_CH_first: tuple[float, float] = (math.nan, math.nan)  # Pa
    trace: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def T_CL_at_first_CH_limit(self) -> float:
        first_CH = next((p for p in self.phases if p.clutch == "CH"), None)
        return first_CH.T_other_end if first_CH else math.nan

    @property
    def T_oncoming_at_stop(self) -> float:
        return self.phases[-1].T_other_end if self.stopped else math.nan


def simulate_creep(params: Params, op: OperatingPoint, T_clutch: dict[str, float], T_oil: float,
                   T_handover: float = 250.0, T_takeover: float = 240.0, horizon: float = 600.0,
                   dt: float = 0.05) -> CreepResult:
    """The idealised strategy on the thermal network (exact step dt), from plates at T_clutch and oil at T_oil.
    A handover falls where the slipping plate crosses T_handover, linearly within its step; the next step starts
    there. Pressure and mu are evaluated at each step's start temperature."""
    net = gearbox_network(params)
    disc = discretize(net, dt)
    T = np.full(len(NODES), float(T_oil))
    idx = {k: NODES.index(k) for k in CLUTCHES}
    for k in CLUTCHES:
        T[idx[k]] = T_clutch[k]
    active = "CL"
    phases = [Phase("CL", 0.0)]
    T_max = {k: float(T[idx[k]]) for k in CLUTCHES}
    mu_CH: list[float] = []
    P_CH: list[float] = []
    ts, T_CL, T_CH = [0.0], [T[idx["CL"]]], [T[idx["CH"]]]
    t, stopped = 0.0, False
    while t < horizon - 1e-9:
        P, mu = pressure_for_torque(params, active, op.torque[active], op.slip[active], T[idx[active]])
        if active == "CH" and sum(p.clutch == "CH" for p in phases) == 1:
            mu_CH.append(mu)
            P_CH.append(P)
        Q = {k: (op.heat[k] if k == active else 0.0) for k in CLUTCHES}
        P_k = {k: (P if k == active else 0.0) for k in CLUTCHES}
        T_new = disc.step(T, heat_sources(params, Q["CL"], Q["CH"], P_k["CL"], P_k["CH"]))
        a = idx[active]
        if T_new[a] >= T_handover:
            frac = (T_handover - T[a]) / (T_new[a] - T[a])  # linear crossing within the step
            T_cross = T + frac * (T_new - T)
            t_cross = t + frac * dt
            other = "CH" if active == "CL" else "CL"
            phases[-1].t_end = t_cross
            phases[-1].T_other_end = float(T_cross[idx[other]])
            if T_cross[idx[other]] >= T_takeover:
                t, T, stopped = t_cross, T_cross, True
                break
            active = other
            phases.append(Phase(active, t_cross))
            t, T = t_cross, T_cross  # the next step starts at the handover
        else:
            t, T = t + dt, T_new
        for k in CLUTCHES:
            T_max[k] = max(T_max[k], float(T[idx[k]]))
        ts.append(t)
        T_CL.append(T[idx["CL"]])
        T_CH.append(T[idx["CH"]])
    if not stopped:
        phases[-1].t_end = t
    slip_time = {k: sum(p.t_end - p.t_start for p in phases if p.clutch == k) for k in CLUTCHES}
    first = (mu_CH[0], mu_CH[-1]) if mu_CH else (math.nan, math.nan)
    first_P = (P_CH[0], P_CH[-1]) if P_CH else (math.nan, math.nan)
    trace = {"t": np.array(ts), "T_CL": np.array(T_CL), "T_CH": np.array(T_CH)}
    return CreepResult(phases, t, stopped, slip_time, T_max, first, first_P, trace)


def run_plant_creep(params: Params, scenario: Scenario, T_handover: float = 250.0, T_takeover: float = 240.0,
                    dt: float = 1e-3, kp: float = 1.5e6, ki: float = 1.5e6, ramp_s: float = 0.5,
                    settle_s: float = 3.0) -> CreepResult:
    """The idealised strategy closed around the full plant on its truth (no bus, no TCU): a PI controller on vehicle
    speed [Pa per m/s, Pa per m] sets the slipping clutch's pressure, feed-forward from the quasi-static load; at
    ``T_handover`` the on-coming clutch takes over (the off-going one ramps out over ``ramp_s``) if it is below
    ``T_takeover``, otherwise both open and the brake holds the vehicle. Creep starts when the brake is released.
    mu_CH and P_CH of the first CH slip are taken from ``settle_s`` after the takeover (the handover transient
    over) to its end. A cross-check of the reduced model, not a TCU."""
    s = scenario
    omega_e = params.engine.omega_idle if s.engine_speed_rpm is None else s.engine_speed_rpm / CV.RAD_S_TO_RPM
    v_des = max(d.desired_speed_mps for d in s.driver if d.creep_request)
    t_start = min(d.t_s for d in s.driver if d.creep_request)
    op = operating_point(params, omega_e, v_des, s.grade_rad)
    feed_forward = {k: pressure_for_torque(params, k, op.torque[k], op.slip[k], 150.0)[0]
                    for k in CLUTCHES}
    plant = Plant(params, dt, T_init=s.initial_temperatures(NODES), v_init=s.v_mps)
    inputs = PlantInputs(brake=1.0, grade=s.grade_rad, engine_speed_request=omega_e)
    out = plant.step(inputs)
    while out.t < t_start - 1e-9:
        out = plant.step(inputs)
    active, integral, ramp_from, P_off = "CL", 0.0, None, 0.0
    phases = [Phase("CL", 0.0)]
    mu_CH: list[float] = []
    P_CH: list[float] = []
    T_max = {"CL": out.T_CL, "CH": out.T_CH}
    stopped = False
    for _ in range(int(round((s.duration_s - t_start) / dt))):
        t = out.t - t_start
        error = v_des - out.v
        integral += error * dt
        P = max(0.0, feed_forward[active] + kp * error + ki * integral)
        cmd = {active: P, "CH" if active == "CL" else "CL": 0.0}
        if ramp_from is not None:
            share = min(1.0, (t - ramp_from) / ramp_s)
            cmd["CH" if active == "CL" else "CL"] = P_off * (1.0 - share)
            ramp_from = None if share >= 1.0 else ramp_from
        out = plant.step(PlantInputs(cmd["CL"], cmd["CH"], 0.0, s.grade_rad, omega_e))
        T = {"CL": out.T_CL, "CH": out.T_CH}
        for k in CLUTCHES:
            T_max[k] = max(T_max[k], T[k])
        if active == "CH" and len(phases) == 2 and t - phases[1].t_start >= settle_s:
            mu_CH.append(out.mu_CH)
            P_CH.append(out.P_CH)
        if ramp_from is None and T[active] >= T_handover:
            other = "CH" if active == "CL" else "CL"
            phases[-1].t_end, phases[-1].T_other_end = out.t - t_start, T[other]
            if T[other] >= T_takeover:
                stopped = True
                break
            active, integral, ramp_from, P_off = other, 0.0, out.t - t_start, P
            phases.append(Phase(active, out.t - t_start))
    if not stopped:
        phases[-1].t_end = out.t - t_start
    slip_time = {k: sum(p.t_end - p.t_start for p in phases if p.clutch == k) for k in CLUTCHES}
    first = (mu_CH[0], mu_CH[-1]) if mu_CH else (math.nan, math.nan)
    first_P = (P_CH[0], P_CH[-1]) if P_CH else (math.nan, math.nan)
    return CreepResult(phases, phases[-1].t_end, stopped, slip_time, T_max, first, first_P)
