"""The plant: assembles engine, hydraulics, both wet clutches, the thermal network and the powertrain, and steps
them at a fixed step (1 ms by default). Deterministic: no clocks, no randomness, no I/O.

Each step (inputs held over it, zero-order hold):

1. engine (governor), the clutch capacities (5)-(6) at the present slip, temperature and pressure, and the road
   load (13) give the torques and friction limits;
2. the torsional model takes its exact step; the friction torques of both clutches and of the vehicle's rolling
   resistance plus brake are solved implicitly, so a clutch whose slip would cross zero locks if it can carry
   the torque, and slips again when it cannot (:func:`dsg_hil.physics.powertrain.solve_contacts`);
3. the friction heat (4), M times the exact integral of the slip over the step, and the hydraulic losses drive
   the exact step of the thermal network; the pressures take their exact first-order step.

The steps run compiled (:func:`advance_steps`, numba through :mod:`dsg_hil.physics.jit`), many per call: the
state and the step-invariant matrices are flat float64 arrays, and :meth:`Plant.advance` takes a whole control
period in one call and returns the outputs at its end (plus the period's peak plate temperatures and friction
energy, :attr:`Plant.period`). :meth:`Plant.step` is one step of it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .physics.engine import governor, net_torque
from .physics.friction import RAD_S_TO_RPM, friction_coefficient, slip_memory_step, torque_per_mu
from .physics.hydraulics import pressure_step
from .physics.jit import compiled, record
from .physics.params import Params
from .physics.powertrain import (
    IDX,
    N_DOF,
    N_SPRING,
    N_STATE,
    Discrete,
    Model,
    build_model,
    road_load,
    solve_contacts,
    vehicle_speed,
)
from .physics.powertrain import discretize as discretize_powertrain
from .physics.thermal import NODES, gearbox_network, heat_sources
from .physics.thermal import discretize as discretize_network

I_CL, I_CH = NODES.index("CL"), NODES.index("CH")
N_T = len(NODES)

# The state as one float64 array: t, x = [omega (7), phi (5)], T (thermal nodes, degC, order of NODES), P_CL,
# P_CH [Pa], governor integral [N m], contact torques M_CL, M_CH, M_R [N m], slip memory of CL, CH [rad/s].
S_T, S_X, S_TEMP = 0, 1, 1 + N_STATE
S_P = S_TEMP + N_T
S_GOV = S_P + 2
S_F = S_GOV + 1
S_MEM = S_F + 3
N_S = S_MEM + 2
# Outputs at the end of a step, in the order of PlantOutputs' fields (bool fields as 0.0 / 1.0).
N_OUT = 27
_O_LOCKED = 22
# The period's extremes and sums (Plant.period): peak plate temperatures [degC], friction energy [J].
PERIOD = ("T_CL_max", "T_CH_max", "E_CL", "E_CH")


@dataclass(frozen=True)
class PlantInputs:
    """What the plant is driven with during one step (or a period of steps)."""

    P_CL_cmd: float = 0.0  # Pa
    P_CH_cmd: float = 0.0  # Pa
    brake: float = 0.0  # 0..1 of the service brake
    grade: float | None = None  # rad; None: the parameter file's beta
    engine_speed_request: float | None = None  # rad/s; None: idle


class PlantState:
    """A reading of the plant's state array (:data:`S_T` ...). ``x = [omega (7), phi (5)]`` of
    :mod:`dsg_hil.physics.powertrain`; arrays are copies (a snapshot, as before the state became one array)."""

    def __init__(self, s: np.ndarray) -> None:
        self.array = s

    @property
    def t(self) -> float:
        return float(self.array[S_T])

    @property
    def x(self) -> np.ndarray:
        return self.array[S_X:S_X + N_STATE].copy()

    @property
    def T(self) -> np.ndarray:  # thermal nodes, degC, order of NODES
        return self.array[S_TEMP:S_TEMP + N_T].copy()

    @property
    def P_CL(self) -> float:  # Pa
        return float(self.array[S_P])

    @property
    def P_CH(self) -> float:  # Pa
        return float(self.array[S_P + 1])

    @property
    def governor_integral(self) -> float:  # N m
        return float(self.array[S_GOV])

    @property
    def contact_torques(self) -> np.ndarray:  # M_CL, M_CH, M_R friction, N m
        return self.array[S_F:S_F + 3].copy()

    @property
    def slip_memory(self) -> np.ndarray:  # |slip| seen by (6), rad/s
        return self.array[S_MEM:S_MEM + 2].copy()


class PlantOutputs(NamedTuple):
    """Sensors a TCU can have, and the plant's truth (marked). A named tuple: immutable and cheap to build
    every step."""

    t: float  # s
    omega_e: float  # engine speed, rad/s
    M_e: float  # net engine torque, N m
    omega_in: float  # clutch input (shaft I / drums), rad/s
    omega_CL: float  # CL output side, rad/s
    omega_CH: float  # CH output side, rad/s
    omega_out: float  # transmission output (shaft III), rad/s
    v: float  # vehicle speed, m/s
    P_CL: float  # Pa
    P_CH: float  # Pa
    T_oil_CL: float  # cooling oil leaving CL, degC
    T_oil_CH: float
    T_sump: float
    T_radiator_out: float
    # truth (simulation only)
    T_CL: float  # plate temperature, degC
    T_CH: float
    mu_CL: float
    mu_CH: float
    M_CL: float  # transmitted clutch torque, N m
    M_CH: float
    Q_CL: float  # friction heat flux, W
    Q_CH: float
    locked_CL: bool
    locked_CH: bool
    vehicle_held: bool
    Q_diss_CL: float = 0.0  # heat leaving the plates (to their oil and E) over the step, W: Q - C dT/dt
    Q_diss_CH: float = 0.0


class Plant:
    """Fixed-step plant. ``advance(inputs, n)`` takes n steps of ``dt`` in one compiled call, ``step(inputs)`` one;
    both return the outputs at the new time."""

    def __init__(self, params: Params, dt: float = 1e-3, T_init: float | dict[str, float] = 25.0,
                 v_init: float = 0.0) -> None:
        if not dt > 0.0:
            raise ValueError(f"dt must be positive, got {dt}")
        self.params = params
        self.dt = dt
        self.model: Model = build_model(params.powertrain, params.vehicle)
        self.disc: Discrete = discretize_powertrain(self.model, dt)
        self.network = gearbox_network(params)
        self.thermal = discretize_network(self.network, dt)
        # Step-invariant products, so that a step costs a few small matrix-vector products. Rows of _Mx/_Mu:
        # the next state (12), the contact velocities (3), the clutch slips integrated over the step (2).
        d = self.disc
        self._Mx = np.ascontiguousarray(np.vstack([d.Phi, d.V @ d.Phi, d.V[:2] @ d.Phi_int]))
        self._Mu = np.ascontiguousarray(np.vstack([d.Gamma, d.V @ d.Gamma, d.V[:2] @ d.Gamma_int]))
        self._VG = np.ascontiguousarray(np.vstack([d.V @ d.Gamma[:, 0], d.V @ d.Gamma[:, 3]]))  # M_e, M_R
        self._W = np.ascontiguousarray(d.W)
        # heat_sources is affine in (Q_CL, Q_CH, P_CL, P_CH): its thermal step, evaluated once per basis input
        zero = np.zeros(N_T)
        self._T_const = self.thermal.step(zero, heat_sources(params, 0.0, 0.0, 0.0, 0.0))
        basis = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        self._T_src = np.ascontiguousarray(np.column_stack(
            [self.thermal.step(zero, heat_sources(params, *b)) - self._T_const for b in basis]))
        self._PhiT = np.ascontiguousarray(self.thermal.Phi)
        C = self.network.C
        # N m per Pa of each clutch (5), plate capacities [J/K], dt, final drive ratio
        self._consts = np.array([torque_per_mu(params.clutch.CL, 1.0), torque_per_mu(params.clutch.CH, 1.0),
                                 C[I_CL], C[I_CH], dt, params.powertrain.i_b])
        self._records = (record(params.friction), record(params.engine), record(params.hydraulics),
                         record(params.vehicle))
        self._s = self._initial_state(T_init, v_init)
        self.state = PlantState(self._s)
        self._u = np.zeros(6)  # P_CL_cmd, P_CH_cmd, brake, grade, engine speed setpoint, number of steps
        self._out = np.zeros(N_OUT)
        self.period = np.zeros(len(PERIOD))  # of the last advance, see PERIOD
        self._no_trace = np.zeros((0, N_OUT))
        self._args = self._kernel_args(self._no_trace)
        self._steps = advance_steps.specialize(*self._args)
        write_outputs(self._s, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, self._consts[5],
                      self._records[3], self._out)
        self._last = self.sample(self._out)

    def _initial_state(self, T_init: float | dict[str, float], v_init: float) -> np.ndarray:
        pt, veh, e = self.params.powertrain, self.params.vehicle, self.params.engine
        if isinstance(T_init, dict):
            T = np.full(N_T, self.params.thermal.T_E)
            for name, value in T_init.items():
                if name not in NODES:
                    raise ValueError(f"unknown thermal node {name!r} (known: {', '.join(NODES)})")
                T[NODES.index(name)] = float(value)
        else:
            T = np.full(N_T, float(T_init))
        omega = np.zeros(N_DOF)
        omega[IDX["e"]] = omega[IDX["in"]] = e.omega_idle
        omega[IDX["1"]] = e.omega_idle / pt.i_a
        omega[IDX["5"]] = v_init / veh.r_w * pt.i_b
        omega[IDX["4"]] = omega[IDX["5"]] * pt.i_1
        omega[IDX["2"]] = omega[IDX["4"]] * pt.i_L
        omega[IDX["3"]] = omega[IDX["4"]] * pt.i_H
        x = np.concatenate([omega, np.zeros(N_SPRING)])
        s = np.zeros(N_S)
        s[S_X:S_X + N_STATE] = x
        s[S_TEMP:S_TEMP + N_T] = T
        s[S_GOV] = e.M_drag
        s[S_MEM:S_MEM + 2] = np.abs(self.disc.V[:2] @ x)
        return s

    def advance(self, inputs: PlantInputs, n_steps: int, trace: np.ndarray | None = None) -> PlantOutputs:
        """Take ``n_steps`` steps with ``inputs`` held; the outputs at the end. :attr:`period` then holds the
        period's peak plate temperatures and friction energy (:data:`PERIOD`). ``trace`` (n_steps x N_OUT), if
        given, receives every step's outputs in the order of :class:`PlantOutputs`' fields."""
        p = self.params
        u = self._u
        u[0], u[1], u[2] = inputs.P_CL_cmd, inputs.P_CH_cmd, inputs.brake
        u[3] = p.vehicle.beta if inputs.grade is None else inputs.grade
        u[4] = p.engine.omega_idle if inputs.engine_speed_request is None else inputs.engine_speed_request
        u[5] = n_steps
        if trace is not None and (trace.shape != (n_steps, N_OUT) or trace.dtype != np.float64
                                  or not trace.flags.c_contiguous):
            raise ValueError(f"trace must be a C-contiguous float64 array of shape {(n_steps, N_OUT)}")
        self._steps(*(self._args if trace is None else self._kernel_args(trace)))
        self._last = self.sample(self._out)
        return self._last

    def _kernel_args(self, trace: np.ndarray) -> tuple:
        return (self._s, self._u, self._Mx, self._Mu, self._VG, self._W, self._PhiT, self._T_const,
                self._T_src, self._consts, *self._records, self._out, self.period, trace)

    def step(self, inputs: PlantInputs) -> PlantOutputs:
        """One step of ``dt``."""
        return self.advance(inputs, 1)

    def outputs(self) -> PlantOutputs:
        """The outputs at the present time (after the last step; before any, with no torque flowing)."""
        return self._last

    @staticmethod
    def sample(row: np.ndarray) -> PlantOutputs:
        """The outputs of a row of :meth:`advance`'s ``trace``."""
        v = row.tolist()
        v[_O_LOCKED:_O_LOCKED + 3] = [flag != 0.0 for flag in v[_O_LOCKED:_O_LOCKED + 3]]
        return PlantOutputs._make(v)


@compiled
def write_outputs(s, M_e, mu_CL, mu_CH, M_CL, M_CH, Q_CL, Q_CH, stuck_CL, stuck_CH, held, Q_diss_CL, Q_diss_CH,
                  i_b, ve, out):
    """The outputs (:class:`PlantOutputs`' fields in order) from the state s and the step's torques and heat."""
    x = s[S_X:]
    T = s[S_TEMP:]
    out[0] = s[S_T]
    out[1] = x[_E]
    out[2] = M_e
    out[3] = x[_1]
    out[4] = x[_2]
    out[5] = x[_3]
    out[6] = x[_5]
    out[7] = vehicle_speed(x[_5], i_b, ve.r_w)
    out[8] = s[S_P]
    out[9] = s[S_P + 1]
    out[10] = T[_I_CLO]
    out[11] = T[_I_CHO]
    out[12] = T[_I_FO]
    out[13] = T[_I_RO]
    out[14] = T[I_CL]
    out[15] = T[I_CH]
    out[16] = mu_CL
    out[17] = mu_CH
    out[18] = M_CL
    out[19] = M_CH
    out[20] = Q_CL
    out[21] = Q_CH
    out[22] = 1.0 if stuck_CL != 0.0 and s[S_P] > 0.0 else 0.0
    out[23] = 1.0 if stuck_CH != 0.0 and s[S_P + 1] > 0.0 else 0.0
    out[24] = held
    out[25] = Q_diss_CL
    out[26] = Q_diss_CH


_I_CLO, _I_CHO, _I_FO, _I_RO = (NODES.index(n) for n in ("CLo", "CHo", "Fo", "Ro"))
_E, _1, _2, _3, _5 = (IDX[n] for n in ("e", "1", "2", "3", "5"))  # speeds as plain ints, for compiled code


@compiled
def advance_steps(s, u, Mx, Mu, VG, W, PhiT, T_const, T_src, c, fr, en, hy, ve, out, period, trace):
    """Plant steps (module docstring) on the state array s in place, with the inputs u = [P_CL_cmd, P_CH_cmd,
    brake, grade, engine speed setpoint, number of steps] held; c = [N m per Pa of CL, CH (5), plate capacities of
    CL, CH, dt, final drive ratio i_b]. Writes the outputs of the last step to ``out``, the period's peaks and sums to
    ``period`` and, if ``trace`` has rows, each step's outputs to them."""
    k_CL, k_CH, C_CL, C_CH, dt, i_b = c[0], c[1], c[2], c[3], c[4], c[5]
    P_CL_cmd, P_CH_cmd, brake, grade, setpoint, n_steps = u[0], u[1], u[2], u[3], u[4], int(u[5])
    n_rows, n_x = Mx.shape
    n_T = PhiT.shape[0]
    free = np.empty(n_rows)
    T_new = np.empty(n_T)
    v_free = np.empty(3)
    cap = np.empty(3)
    torques = np.empty(4)
    sources = np.empty(4)
    period[0] = s[S_TEMP + I_CL]
    period[1] = s[S_TEMP + I_CH]
    period[2] = 0.0
    period[3] = 0.0
    for k in range(n_steps):
        x = s[S_X:S_X + n_x]
        T = s[S_TEMP:S_TEMP + n_T]
        T_plate_CL, T_plate_CH = T[I_CL], T[I_CH]
        P_CL, P_CH = s[S_P], s[S_P + 1]
        M_fixed, M_resist = road_load(vehicle_speed(x[_5], i_b, ve.r_w), grade, brake, ve)
        fuel, d_integral = governor(x[_E], s[S_GOV], setpoint, en)
        M_e = net_torque(fuel, en)
        # clutch capacities (5)-(6), mu at the remembered slip (static mu once stuck long enough)
        mu_CL = friction_coefficient(s[S_MEM] * RAD_S_TO_RPM, T_plate_CL, P_CL / 1e6, fr)
        mu_CH = friction_coefficient(s[S_MEM + 1] * RAD_S_TO_RPM, T_plate_CH, P_CH / 1e6, fr)
        cap[0], cap[1], cap[2] = mu_CL * k_CL * P_CL, mu_CH * k_CH * P_CH, M_resist
        # free motion, then the friction torques of the three contacts, implicitly (stick/slip)
        for i in range(n_rows):
            acc = 0.0
            for j in range(n_x):
                acc += Mx[i, j] * x[j]
            free[i] = acc
        for i in range(3):
            v_free[i] = free[n_x + i] + VG[0, i] * M_e + VG[1, i] * M_fixed
        f = solve_contacts(v_free, W, cap, s[S_F:S_F + 3])
        torques[0], torques[1], torques[2], torques[3] = M_e, f[0], f[1], M_fixed + f[2]
        for i in range(n_rows):
            acc = free[i]
            for j in range(4):
                acc += Mu[i, j] * torques[j]
            free[i] = acc
        slip_int_CL, slip_int_CH = free[n_x + 3], free[n_x + 4]  # rad, exact over the step
        Q_CL = max(f[0] * slip_int_CL, 0.0) / dt  # friction heat (4), W
        Q_CH = max(f[1] * slip_int_CH, 0.0) / dt
        # thermal network: exact step with the sources of heat_sources(Q_CL, Q_CH, P_CL, P_CH)
        sources[0], sources[1], sources[2], sources[3] = Q_CL, Q_CH, P_CL, P_CH
        for i in range(n_T):
            acc = 0.0
            for j in range(n_T):
                acc += PhiT[i, j] * T[j]
            acc += T_const[i]
            for j in range(4):
                acc += T_src[i, j] * sources[j]
            T_new[i] = acc
        x[:] = free[:n_x]
        T[:] = T_new
        s[S_F], s[S_F + 1], s[S_F + 2] = f[0], f[1], f[2]
        s[S_MEM] = slip_memory_step(s[S_MEM], slip_int_CL / dt, dt, fr)
        s[S_MEM + 1] = slip_memory_step(s[S_MEM + 1], slip_int_CH / dt, dt, fr)
        s[S_GOV] += d_integral * dt
        s[S_P] = pressure_step(P_CL, P_CL_cmd, dt, hy)
        s[S_P + 1] = pressure_step(P_CH, P_CH_cmd, dt, hy)
        s[S_T] += dt
        stuck_CL = 1.0 if abs(f[0]) < cap[0] * (1.0 - 1e-9) else 0.0
        stuck_CH = 1.0 if abs(f[1]) < cap[1] * (1.0 - 1e-9) else 0.0
        held = 1.0 if abs(f[2]) < cap[2] * (1.0 - 1e-9) else 0.0
        write_outputs(s, M_e, mu_CL, mu_CH, f[0], f[1], Q_CL, Q_CH, stuck_CL, stuck_CH, held,
                      Q_CL - C_CL * (T_new[I_CL] - T_plate_CL) / dt, Q_CH - C_CH * (T_new[I_CH] - T_plate_CH) / dt,
                      i_b, ve, out)
        period[0] = max(period[0], T_new[I_CL])
        period[1] = max(period[1], T_new[I_CH])
        period[2] += Q_CL * dt
        period[3] += Q_CH * dt
        if k < trace.shape[0]:
            trace[k, :] = out
