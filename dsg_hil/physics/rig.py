"""The single-clutch test rig of Section III.C: clutch CL slips at constant pressure and relative speed.

The friction coefficient (6) and torque (5) set the friction heat (4) into the plates of the gearbox network in its
rig configuration (:func:`rig_configuration`): the test clutch (``clutch.test``, two friction surfaces) with the
rig's lubrication (``thermal.clutch.test``) takes the place of element CL. The rig starts in thermal equilibrium:
every node and the environment E at the start temperature (40 degC in the paper), so the rise is the clutch's own
doing.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..common.units import CV
from .friction import friction_coefficient, torque_per_mu
from .jit import compiled
from .params import Params
from .thermal import NODES, discretize, gearbox_network, heat_sources

__all__ = ["I_CL", "RigCase", "RigTrace", "rig_configuration", "rig_steps", "run_rig"]

I_CL = NODES.index("CL")


@dataclass(frozen=True)
class RigCase:
    pressure_mpa: float
    speed_rpm: float


@dataclass(frozen=True)
class RigTrace:
    """Time series of one rig run (sampled every ``every`` steps)."""

    case: RigCase
    t: np.ndarray  # s
    T_CL: np.ndarray  # plate temperature, degC
    torque: np.ndarray  # N*m
    mu: np.ndarray
    T_nodes: np.ndarray  # all nodes at the end, degC
    friction_work: float  # J
    heat_to_environment: float  # J, integrated
    heat_stored: float  # J, sum C (T_end - T_start)
    hydraulic_heat: float  # J, pump + throttle sources

    @property
    def temperature_rise(self) -> float:
        return float(self.T_CL[-1] - self.T_CL[0])


def rig_configuration(params: Params, T_start: float) -> Params:
    """The parameters of the Section III.C rig: the test clutch and its lubrication in slot CL, E at T_start.
    The rig has no second clutch: slot CH keeps the vehicle's pack but no cooling flow, so it stays at T_start
    and nothing of the vehicle's CH reaches the rig's results."""
    cool = params.thermal.clutch
    clutch = replace(params.clutch, CL=params.clutch.test)
    cool = replace(cool, CL=cool.test, CH=replace(cool.CH, Q_cool=0.0))
    return replace(params, clutch=clutch, thermal=replace(params.thermal, T_E=T_start, clutch=cool))


def run_rig(params: Params, case: RigCase, duration: float = 100.0, dt: float = 1e-3,
            T_start: float = 40.0, every: int = 100) -> RigTrace:
    """Simulate the rig for ``duration`` s at step ``dt``; exact ZOH thermal step, friction evaluated per step
    (compiled: :func:`rig_steps`)."""
    params = rig_configuration(params, T_start)
    geometry = params.clutch.CL
    net = gearbox_network(params)
    disc = discretize(net, dt)
    T = np.full(len(NODES), float(T_start))
    T0 = T.copy()
    P = case.pressure_mpa * CV.MPA_TO_PA
    omega = case.speed_rpm / CV.RAD_S_TO_RPM
    k_mu = torque_per_mu(geometry, P)
    q_base = heat_sources(params, 0.0, 0.0, P, 0.0)
    q = q_base.copy()
    drive = disc.Gamma @ ((net.g_E * net.T_E + q_base) / net.C)  # the constant part of the source term
    gamma_CL = disc.Gamma[:, I_CL] / net.C[I_CL]
    n_steps = int(round(duration / dt))
    rows = list(range(0, n_steps, every)) + [n_steps]
    samples = np.empty((len(rows), 3))  # T_CL, torque, mu at the sampled steps
    work, to_env = rig_steps(T, n_steps, every, omega, P, k_mu, disc.Phi, drive, gamma_CL, net.g_E, net.T_E, dt,
                             params.friction, samples)
    return RigTrace(case, np.array(rows) * dt, samples[:, 0], samples[:, 1], samples[:, 2], T,
                    work, to_env, float(net.C @ (T - T0)), float(q.sum()) * n_steps * dt)


@compiled
def rig_steps(T, n_steps, every, omega, P, k_mu, Phi, drive, gamma_CL, g_E, T_E, dt, fr, samples):
    """The rig's n_steps exact thermal steps on T in place, friction (5)-(6) at each step's start temperature;
    T_CL, torque and mu every ``every`` steps and at the end into ``samples``; slip speed ``omega`` [rad/s] and
    pressure ``P`` [Pa] held. Returns (friction work, heat to E) [J], the latter by the trapezoid rule."""
    n = T.shape[0]
    T_next = np.empty(n)
    work = to_env = 0.0
    row = 0
    for k in range(n_steps + 1):
        mu = friction_coefficient(omega, T[I_CL], P, fr)
        M = mu * k_mu
        if k % every == 0 or k == n_steps:
            samples[row, 0], samples[row, 1], samples[row, 2] = T[I_CL], M, mu
            row += 1
        if k == n_steps:
            break
        heat = M * omega
        out_before = out_after = 0.0
        for i in range(n):
            acc = drive[i] + gamma_CL[i] * heat
            for j in range(n):
                acc += Phi[i, j] * T[j]
            T_next[i] = acc
        for i in range(n):
            out_before += g_E[i] * (T[i] - T_E)
            out_after += g_E[i] * (T_next[i] - T_E)
        work += heat * dt
        to_env += 0.5 * (out_before + out_after) * dt
        T[:] = T_next
    return work, to_env
