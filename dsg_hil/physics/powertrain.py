"""Torsional powertrain and vehicle of Fig. 6, equations (7)-(17), for both clutch paths.

Degrees of freedom (speeds [rad/s]): engine ``e`` (7), input shaft ``in`` (8), shaft I with both clutch drums ``1``
(9), CL output ``2`` (10), CH output ``3`` (10 for i_H), shaft II ``4`` (11), shaft III with the vehicle ``5`` (12).
Springs (twists [rad]): ``in`` (14), ``a1`` (15), ``a2L`` (16), ``a2H`` (16 for i_H), ``a3`` (17). A spring with
ratio i and efficiency eta between a and b has twist rate ``omega_a / i - omega_b``, torque ``M = K phi + C phi'``,
and loads a with ``-M / (i eta)`` and b with ``+M``, as in (8)-(12).

The acceleration term delta m dv/dt of (13) is the vehicle's translational inertia delta m r_w^2 at the wheel; it
is moved to the left-hand side of (12) so that the system stays explicit.

External torques ``u = [M_e, M_CL, M_CH, M_R]``: engine (times eta_e, (7)), the clutches (from shaft I to their
outputs) and the road load (13) at the wheel (reflected by 1/(i_b eta_b), (12)). With u held over a step the
equations are linear with constant coefficients, so :func:`discretize` gives their exact solution.

Stick/slip: the two clutches and the vehicle's rolling resistance plus brake are three friction contacts. Their
torques are found implicitly (:func:`solve_contacts`): a clutch whose slip would cross zero within the step locks
(its mean slip over the step zero) if it can carry the torque that takes, and unlocks when it cannot; the same holds
the vehicle at standstill (its speed at the step's end zero, :func:`law_rows`). This time-stepping law cannot
chatter, and a torque held over the step does exactly its work on the mean velocity, at the 1 ms step although the
shafts have modes up to ~690 Hz (:mod:`dsg_hil.physics.plant`).

Rolling resistance at standstill (:func:`holding_torque`): the brake is static friction, but the wheel resistance
of (13) is not. Tyre rolling resistance is hysteresis loss of a rolling tyre and vanishes at rest; a standing
vehicle is held only by its breakaway resistance ``f_breakaway`` (tyres, bearings, drag: ``vehicle.f_breakaway``),
far below Table I's f = 0.123, which is the paper's resistance while creeping. Between, the resistance rises
linearly with speed from the breakaway value to f at ``vehicle.v_stick`` (a regularised law: a rise at one speed,
kinetic above static, would chatter at standstill). So a vehicle on a grade steeper than ``f_breakaway`` rolls
down it, at the speed where the law balances the gradient, and one on a gentler grade stands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .jit import compiled
from .params import Powertrain, Vehicle
from .thermal import zoh

__all__ = ["CONTACTS", "CONTACT_INPUTS", "DOFS", "Discrete", "IDX", "INPUTS", "Model", "N_DOF", "N_SPRING", "N_STATE",
           "SPRINGS", "brake_for_decel", "build_model", "contact_velocities", "discretize", "holding_torque",
           "law_rows", "road_load", "solve_contacts", "solve_contacts_into", "vehicle_speed"]

DOFS = ("e", "in", "1", "2", "3", "4", "5")
SPRINGS = ("in", "a1", "a2L", "a2H", "a3")
INPUTS = ("M_e", "M_CL", "M_CH", "M_R")
N_DOF, N_SPRING = len(DOFS), len(SPRINGS)
N_STATE = N_DOF + N_SPRING
IDX = {name: i for i, name in enumerate(DOFS)}


@dataclass(frozen=True)
class Model:
    """Continuous model: J omega' = T_s (K phi + C S omega) + B u, phi' = S omega (x = [omega, phi])."""

    J: np.ndarray  # (7,) inertias [kg m^2]
    S: np.ndarray  # (5, 7) twist rates
    T_s: np.ndarray  # (7, 5) spring torque distribution
    K: np.ndarray  # (5,)
    C: np.ndarray  # (5,)
    B: np.ndarray  # (7, 4)

    def forces(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Torque on each DOF [N m] for state x = [omega, phi] and inputs u."""
        omega, phi = x[:N_DOF], x[N_DOF:]
        return self.T_s @ (self.K * phi + self.C * (self.S @ omega)) + self.B @ u

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(A, B_x) of x' = A x + B_x u."""
        A = np.zeros((N_STATE, N_STATE))
        A[:N_DOF, :N_DOF] = self.T_s @ (self.C[:, None] * self.S) / self.J[:, None]
        A[:N_DOF, N_DOF:] = self.T_s * self.K[None, :] / self.J[:, None]
        A[N_DOF:, :N_DOF] = self.S
        B_x = np.zeros((N_STATE, len(INPUTS)))
        B_x[:N_DOF] = self.B / self.J[:, None]
        return A, B_x

    def derivative(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """dx/dt [rad/s^2, rad/s]."""
        return np.concatenate([self.forces(x, u) / self.J, self.S @ x[:N_DOF]])


def build_model(pt: Powertrain, vehicle: Vehicle) -> Model:
    J = np.array([
        pt.I_e,
        pt.I_in + pt.I_m,
        pt.I_1,
        pt.I_2 + pt.I_40 / pt.i_L**2,
        pt.I_3 + pt.I_40 / pt.i_H**2,
        pt.I_4 + pt.I_50 / pt.i_1**2,
        pt.I_5 + (pt.I_R + vehicle.delta * vehicle.m * vehicle.r_w**2) / pt.i_b**2,
    ])
    springs = (  # a, b, ratio, efficiency, K, C
        ("e", "in", 1.0, 1.0, pt.K_in, pt.C_in),
        ("in", "1", pt.i_a, pt.eta_a, pt.K_a1, pt.C_a1),
        ("2", "4", pt.i_L, pt.eta_L, pt.K_a2, pt.C_a2),
        ("3", "4", pt.i_H, pt.eta_H, pt.K_a2, pt.C_a2),
        ("4", "5", pt.i_1, pt.eta_1, pt.K_a3, pt.C_a3),
    )
    S = np.zeros((N_SPRING, N_DOF))
    T_s = np.zeros((N_DOF, N_SPRING))
    for k, (a, b, i, eta, _, _) in enumerate(springs):
        S[k, IDX[a]], S[k, IDX[b]] = 1.0 / i, -1.0
        T_s[IDX[a], k], T_s[IDX[b], k] = -1.0 / (i * eta), 1.0
    B = np.zeros((N_DOF, len(INPUTS)))
    B[IDX["e"], 0] = pt.eta_e
    B[IDX["1"], 1], B[IDX["2"], 1] = -1.0, 1.0
    B[IDX["1"], 2], B[IDX["3"], 2] = -1.0, 1.0
    B[IDX["5"], 3] = -1.0 / (pt.i_b * pt.eta_b)
    return Model(J, S, T_s, np.array([s[4] for s in springs]), np.array([s[5] for s in springs]), B)


# The three friction contacts: each has a velocity (row of x) that its friction torque (an input) reduces.
CONTACTS = ("CL", "CH", "vehicle")
CONTACT_INPUTS = (1, 2, 3)  # M_CL, M_CH, M_R


def contact_velocities() -> np.ndarray:
    """V (3 x 12): CL slip omega_1 - omega_2, CH slip omega_1 - omega_3, shaft III speed omega_5."""
    V = np.zeros((3, N_STATE))
    V[0, IDX["1"]], V[0, IDX["2"]] = 1.0, -1.0
    V[1, IDX["1"]], V[1, IDX["3"]] = 1.0, -1.0
    V[2, IDX["5"]] = 1.0
    return V


@dataclass(frozen=True)
class Discrete:
    """Exact zero-order-hold step of the linear model and of the integral of its state over the step.

    ``x[k+1] = Phi x[k] + Gamma u[k]`` and ``int_0^dt x dt = Phi_int x[k] + Gamma_int u[k]``.
    ``L_x x + L_u u`` are the velocities the contact law acts on (:func:`law_rows`): the clutches' slips' means over
    the step, the vehicle's (shaft III) speed at the step's end. ``W = L_u[:, contacts]`` is their (constant)
    response to the friction torques.
    """

    dt: float
    Phi: np.ndarray
    Gamma: np.ndarray
    Phi_int: np.ndarray
    Gamma_int: np.ndarray
    V: np.ndarray
    L_x: np.ndarray
    L_u: np.ndarray
    W: np.ndarray


def discretize(model: Model, dt: float) -> Discrete:
    if not dt > 0.0:
        raise ValueError(f"dt must be positive, got {dt}")
    A, B_x = model.matrices()
    n = N_STATE
    aug = np.zeros((2 * n, 2 * n))  # [x; X] with X' = x
    aug[:n, :n] = A
    aug[n:, :n] = np.eye(n)
    E, G = zoh(aug, dt)
    B_aug = np.vstack([B_x, np.zeros_like(B_x)])
    Gam = G @ B_aug
    V = contact_velocities()
    L_x, L_u = law_rows((E[:n, :n], Gam[:n]), (E[n:, :n], Gam[n:]), V, dt)
    return Discrete(dt, E[:n, :n], Gam[:n], E[n:, :n], Gam[n:], V, L_x, L_u, L_u[:, CONTACT_INPUTS])


def law_rows(end: tuple[np.ndarray, np.ndarray], integral: tuple[np.ndarray, np.ndarray], V: np.ndarray,
             dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(L_x, L_u): the velocities the contact law acts on, ``L_x x + L_u u`` over a step from x with u held, given
    the step's ``end = (Phi, Gamma)`` and ``integral = (Phi_int, Gamma_int)`` (:class:`Discrete`).

    The clutches (rows 0, 1): their slips' MEANS over the step, ``V (Phi_int x + Gamma_int u) / dt``, so a locked
    clutch does no work and a slipping one dissipates |M| times its slip integral exactly (module docstring of
    :mod:`dsg_hil.physics.plant`). The vehicle (row 2): shaft III's speed at the step's END, ``V (Phi x + Gamma u)``,
    so a held vehicle ends every step at rest. On the mean, a held vehicle that entered the step moving would end
    it moving the other way as fast (v_end = -v_start for its near-linear speed within a step: its inertia is the
    vehicle's), and that reversal is an undamped mode at the step's Nyquist frequency: braked from 0.2 m/s, the
    speed rang at +-0.34 mm/s decaying with tau ~ 120 s, read as roll-back. The clutches' sides are light
    and stiffly coupled: a locked clutch's end slip stays at ~1e-6 rad/s on the mean law, which keeps the shuffle
    and the 88-Hz mode (bench/contact_law.py)."""
    L_x = np.vstack([V[:2] @ integral[0] / dt, V[2:] @ end[0]])
    L_u = np.vstack([V[:2] @ integral[1] / dt, V[2:] @ end[1]])
    return L_x, L_u


@compiled
def solve_contacts(v_free: np.ndarray, W: np.ndarray, cap: np.ndarray, limit: np.ndarray, v_ramp: np.ndarray,
                   f0: np.ndarray, iterations: int = 50, tol: float = 1e-9) -> np.ndarray:
    """Friction torques f (one per contact) of the implicit time-stepping friction law.

    With ``v = v_free + W f`` the contact velocities the law acts on: a contact sticks (v_i = 0) when it can, with
    |f_i| <= cap_i; otherwise it slips, never reversing within the step, with |f_i| rising linearly with |v_i|
    from cap_i to ``limit_i`` at ``v_ramp_i`` and ``limit_i`` beyond (``limit = cap``: Coulomb friction; the
    vehicle's rolling resistance rises with speed, see the module docstring). Projected Gauss-Seidel from ``f0``
    in a fixed order (deterministic); W has a dominant negative diagonal. Float arrays in and out (compiled: scalar
    loops cost nothing there).
    """
    f = f0.astype(np.float64)  # a new array: f0 is left as it is
    solve_contacts_into(v_free, W, cap, limit, v_ramp, f, iterations, tol)
    return f


@compiled
def solve_contacts_into(v_free: np.ndarray, W: np.ndarray, cap: np.ndarray, limit: np.ndarray,
                        v_ramp: np.ndarray, f: np.ndarray, iterations: int = 50, tol: float = 1e-9) -> None:
    """:func:`solve_contacts` in place: ``f`` holds the starting torques f0 on entry, the solution on return (the
    plant's step allocates nothing)."""
    n = cap.shape[0]
    for i in range(n):
        f[i] = min(max(f[i], -limit[i]), limit[i])
    scale = tol * (1.0 + limit.max())
    for _ in range(iterations):
        change = 0.0
        for i in range(n):
            v_i = v_free[i]
            for j in range(n):
                v_i += W[i, j] * f[j]
            new = f[i] - v_i / W[i, i]  # the torque that sticks it
            if new > cap[i] or new < -cap[i]:
                s = 1.0 if new > 0.0 else -1.0
                new = s * limit[i]
                rise = limit[i] - cap[i]
                if rise > 0.0:  # slipping at v = a + W_ii f (a: without its own torque), f rising with |v|
                    v = (v_i - W[i, i] * (f[i] - s * cap[i])) / (1.0 - W[i, i] * rise / v_ramp[i])
                    if abs(v) < v_ramp[i]:
                        new = s * cap[i] + rise * v / v_ramp[i]
            if abs(new - f[i]) > change:
                change = abs(new - f[i])
            f[i] = new
        if change <= scale:
            break


@compiled
def vehicle_speed(omega_5: float, i_b: float, r_w: float) -> float:
    """Vehicle speed [m/s] from shaft III speed omega_5 [rad/s] (12): final drive ratio i_b, wheel radius r_w."""
    return omega_5 / i_b * r_w


def brake_for_decel(decel: float, vehicle: Vehicle) -> float:
    """Brake request (0..1 of ``M_brake_max``) for a deceleration ``decel`` [m/s^2] asked of the service brakes, as a
    brake controller (ESC) takes a deceleration request: the wheel torque m decel r_w that decelerates this vehicle by
    that much on its own, clamped to the brake's range (0 for none or less). The ESC knows the vehicle's mass (its
    own estimate, here the truth) and closes no loop of its own: the requester's speed control does."""
    if not decel > 0.0 or vehicle.M_brake_max <= 0.0:
        return 0.0
    return min(vehicle.m * decel * vehicle.r_w / vehicle.M_brake_max, 1.0)


@compiled
def road_load(v: float, grade: float, brake: float, vehicle: Vehicle) -> tuple[float, float]:
    """Road load (13) at the wheel without its acceleration term, split into (drive-independent, resisting) [N m].

    Returns ``(M_fixed, M_resist)``: ``M_fixed`` = air drag (signed with v) + gradient, ``M_resist`` = magnitude of
    rolling resistance plus brake, which opposes motion (in full from ``v_stick`` on); a standing vehicle is held
    only up to :func:`holding_torque`.
    """
    air = 0.5 * vehicle.rho_air * vehicle.C_D * vehicle.A * v * abs(v)
    gradient = vehicle.m * vehicle.g * math.sin(grade)
    rolling = vehicle.m * vehicle.g * vehicle.f * math.cos(grade)
    resist = rolling * vehicle.r_w + min(max(brake, 0.0), 1.0) * vehicle.M_brake_max
    return (air + gradient) * vehicle.r_w, resist


@compiled
def holding_torque(grade: float, brake: float, vehicle: Vehicle) -> float:
    """The most torque at the wheel [N m] that holds a standing vehicle: the brake plus the breakaway rolling
    resistance ``f_breakaway m g cos(grade) r_w`` (module docstring). Of :func:`road_load`'s ``M_resist``, the rest
    acts only on a moving vehicle, in full from ``v_stick`` on."""
    breakaway = vehicle.m * vehicle.g * vehicle.f_breakaway * math.cos(grade) * vehicle.r_w
    return breakaway + min(max(brake, 0.0), 1.0) * vehicle.M_brake_max
