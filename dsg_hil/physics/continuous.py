"""The plant's equations in continuous time, for checking the fixed-step plant against a tight-tolerance
``scipy.integrate.solve_ivp`` solution: the same physics functions as :mod:`dsg_hil.physics.plant`, evaluated
continuously instead of held over a step.

:func:`rhs` holds while no contact changes mode (both clutches slip, the vehicle rolls, or any fixed set of contacts
stuck). :func:`solve_hybrid` follows stick/slip as events: a slipping contact whose velocity reaches zero sticks if
the torque that holds it is within its capacity (else it reverses), a stuck one slips when that torque exceeds it;
while stuck, its friction torque is the one that keeps its velocity's rate zero (a linear solve).

State ``y = [omega (7), phi (5), T (14 nodes), P_CL, P_CH, governor integral, slip memory CL, CH]``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.integrate import solve_ivp

from . import engine
from .friction import friction_coefficient, torque_per_mu
from .hydraulics import clamp_command
from .powertrain import IDX, N_DOF, N_STATE, contact_velocities, holding_torque, road_load, vehicle_speed
from .thermal import NODES, heat_sources
from .plant import Plant, PlantInputs

N_T = len(NODES)
NO_CONTACT_STUCK = (False, False, False)
# g(y, stuck, direction) -> (u, f, cap, governor rate): see torques()
Torques = Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray, float]]


def pack(plant: Plant) -> np.ndarray:
    s = plant.state
    return np.concatenate([s.x, s.T, [s.P_CL, s.P_CH, s.governor_integral], s.slip_memory])


def torques(plant: Plant, inputs: PlantInputs) -> Torques:
    """g(y, stuck, direction) -> (u = [M_e, M_CL, M_CH, M_R], friction torques f, capacities, governor rate).

    A slipping contact's friction is its capacity (5)-(6) times ``direction`` (+-1; None: the sign of its
    velocity); the vehicle's is its holding torque (breakaway rolling resistance plus brake) times ``direction``
    plus the rest of the rolling resistance (13) in proportion to its speed up to ``v_stick``
    (:mod:`dsg_hil.physics.powertrain`); a stuck one's is the torque that keeps its velocity constant, all stuck
    contacts solved together. ``cap`` holds what each contact can hold at rest."""
    p = plant.params
    grade = p.vehicle.beta if inputs.grade is None else inputs.grade
    setpoint = p.engine.omega_idle if inputs.engine_speed_request is None else inputs.engine_speed_request
    k_CL, k_CH = torque_per_mu(p.clutch.CL, 1.0), torque_per_mu(p.clutch.CH, 1.0)
    i_CL, i_CH = NODES.index("CL"), NODES.index("CH")
    A, B_x = plant.model.matrices()
    V = contact_velocities()
    VA, VB = V @ A, V @ B_x
    omega_full = p.vehicle.v_stick / p.vehicle.r_w * p.powertrain.i_b  # shaft III speed of v_stick

    def g(y: np.ndarray, stuck: Sequence[bool] = NO_CONTACT_STUCK,
          direction: Sequence[float] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        x, T = y[:N_STATE], y[N_STATE:N_STATE + N_T]
        P_CL, P_CH, integral, mem_CL, mem_CH = y[N_STATE + N_T:]
        mu_CL = friction_coefficient(mem_CL, T[i_CL], P_CL, p.friction)
        mu_CH = friction_coefficient(mem_CH, T[i_CH], P_CH, p.friction)
        v = vehicle_speed(x[IDX["5"]], p.powertrain.i_b, p.vehicle.r_w)
        M_fixed, M_resist = road_load(v, grade, inputs.brake, p.vehicle)
        M_hold = holding_torque(grade, inputs.brake, p.vehicle)
        cap = np.array([mu_CL * k_CL * P_CL, mu_CH * k_CH * P_CH, M_hold])
        d = np.copysign(1.0, V @ x) if direction is None else np.asarray(direction, dtype=float)
        held = np.flatnonzero(stuck)
        f = np.where(stuck, 0.0, cap * d)
        if not stuck[2]:
            f[2] += (M_resist - M_hold) * min(max(x[IDX["5"]] / omega_full, -1.0), 1.0)
        fuel, d_integral = engine.governor(x[IDX["e"]], integral, setpoint, p.engine)
        u = np.array([engine.net_torque(fuel, p.engine), f[0], f[1], M_fixed + f[2]])
        if held.size:
            f[held] = np.linalg.solve(VB[np.ix_(held, held + 1)], -(VA[held] @ x + VB[held] @ u))
            u[held + 1] += f[held]
        return u, f, cap, d_integral

    return g


def rhs(plant: Plant, inputs: PlantInputs, stuck: Sequence[bool] = NO_CONTACT_STUCK,
        direction: Sequence[float] | None = None) -> Callable[[float, np.ndarray], np.ndarray]:
    """f(t, y) for solve_ivp, with the inputs held constant and the contacts in the given modes."""
    p = plant.params
    g = torques(plant, inputs)
    V = contact_velocities()[:2]
    tau = p.hydraulics.tau
    target = [clamp_command(inputs.P_CL_cmd, p.hydraulics), clamp_command(inputs.P_CH_cmd, p.hydraulics)]

    def f(t: float, y: np.ndarray) -> np.ndarray:
        x, T = y[:N_STATE], y[N_STATE:N_STATE + N_T]
        P_CL, P_CH, _, mem_CL, mem_CH = y[N_STATE + N_T:]
        u, M, _, d_integral = g(y, stuck, direction)
        slip_CL, slip_CH = V @ x
        q = heat_sources(p, abs(M[0] * slip_CL), abs(M[1] * slip_CH), P_CL, P_CH)
        return np.concatenate([
            plant.model.derivative(x, u),
            plant.network.derivative(T, q),
            [(target[0] - P_CL) / tau, (target[1] - P_CH) / tau, d_integral,
             (abs(slip_CL) - mem_CL) / p.friction.tau_slip, (abs(slip_CH) - mem_CH) / p.friction.tau_slip],
        ])

    return f


def solve_hybrid(plant: Plant, inputs_at: Callable[[float], PlantInputs], breakpoints: Sequence[float],
                 t_eval: np.ndarray, rtol: float = 1e-10) -> tuple[np.ndarray, int]:
    """solve_ivp (Radau, rtol = atol) from the plant's state with stick/slip as events (module docstring); the
    inputs ``inputs_at(t)`` constant between ``breakpoints`` (ascending, the last one the end). Returns (y at
    t_eval as rows, number of mode changes)."""
    V = contact_velocities()
    y, t = pack(plant), 0.0
    stuck, direction = [False, False, False], [float(d) for d in np.copysign(1.0, V @ y[:N_STATE])]
    out, changes = [], 0
    for t_end in breakpoints:
        g = torques(plant, inputs_at(t))
        stuck, direction = _settle(g, y, stuck, direction, V, decided=())
        while t < t_end:
            events = [_event(g, c, tuple(stuck), tuple(direction), V) for c in range(3)]
            sol = solve_ivp(rhs(plant, inputs_at(t), tuple(stuck), tuple(direction)), (t, t_end), y,
                            method="Radau", rtol=rtol, atol=rtol, events=events, dense_output=True)
            if not sol.success:
                raise RuntimeError(f"solve_ivp failed at t={t}: {sol.message}")
            t_next = float(sol.t[-1])
            ts = t_eval[(t_eval > t) & (t_eval <= t_next)]
            if ts.size:
                out.extend(sol.sol(ts).T)
            t, y = t_next, sol.y[:, -1]
            if sol.status == 1:  # a contact changes mode
                fired = next(c for c in range(3) if sol.t_events[c].size)
                if stuck[fired]:  # the torque holding it reached its capacity: it slips the way that torque acts
                    f = g(y, tuple(stuck), tuple(direction))[1]
                    stuck[fired], direction[fired] = False, float(np.copysign(1.0, f[fired]))
                    stuck, direction = _settle(g, y, stuck, direction, V, decided=(fired,))
                else:
                    stuck, direction = _settle(g, y, stuck, direction, V, decided=(), reached=fired)
                changes += 1
    return np.array(out), changes


def _event(g: Torques, c: int, stuck: tuple, direction: tuple, V: np.ndarray) -> Callable[[float, np.ndarray], float]:
    """Contact c's mode change: a stuck one's holding torque reaching its capacity, a slipping one's velocity
    crossing zero against its direction."""
    if stuck[c]:
        def event(t: float, y: np.ndarray) -> float:
            _, f, cap, _ = g(y, stuck, direction)
            return float(abs(f[c]) - cap[c])
        event.direction = 1.0  # type: ignore[attr-defined]
    else:
        def event(t: float, y: np.ndarray) -> float:
            return float(V[c] @ y[:N_STATE])
        event.direction = -direction[c]  # type: ignore[attr-defined]
    event.terminal = True  # type: ignore[attr-defined]
    return event


def _settle(g: Torques, y: np.ndarray, stuck: list, direction: list, V: np.ndarray, decided: tuple,
            reached: int = -1) -> tuple[list, list]:
    """Consistent modes at y: stuck contacts whose holding torque exceeds their capacity slip; slipping ones at
    zero velocity (``reached``, or below 1e-9) stick if they can be held, else slip the way the holding torque
    acts. Contacts in ``decided`` keep their mode."""
    stuck, direction, done = list(stuck), list(direction), set(decided)
    for _ in range(10):
        _, f, cap, _ = g(y, tuple(stuck), tuple(direction))
        over = [c for c in range(3) if stuck[c] and c not in done and abs(f[c]) > cap[c]]
        if over:
            c = over[0]
            stuck[c], direction[c] = False, float(np.copysign(1.0, f[c]))
            done.add(c)
            continue
        at_zero = [c for c in range(3) if not stuck[c] and c not in done
                   and (c == reached or abs(V[c] @ y[:N_STATE]) < 1e-9)]
        if not at_zero:
            break
        c = at_zero[0]
        trial = [*stuck[:c], True, *stuck[c + 1:]]
        _, f, cap, _ = g(y, tuple(trial), tuple(direction))
        if abs(f[c]) <= cap[c]:
            stuck = trial
        else:
            direction[c] = float(np.copysign(1.0, f[c]))
        done.add(c)
    return stuck, direction


__all__ = ["N_DOF", "N_STATE", "N_T", "pack", "rhs", "solve_hybrid", "torques"]
