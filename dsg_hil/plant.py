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
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .physics import engine, hydraulics
from .physics.friction import RAD_S_TO_RPM, friction_coefficient, slip_memory_step, torque_per_mu
from .physics.params import Params
from .physics.powertrain import (IDX, N_DOF, N_SPRING, N_STATE, Discrete, Model, build_model, contact_velocities,
                                 road_load, solve_contacts, vehicle_speed)
from .physics.powertrain import discretize as discretize_powertrain
from .physics.thermal import NODES, gearbox_network, heat_sources
from .physics.thermal import discretize as discretize_network

I_CL, I_CH = NODES.index("CL"), NODES.index("CH")


@dataclass(frozen=True)
class PlantInputs:
    """What the plant is driven with during one step."""

    P_CL_cmd: float = 0.0  # Pa
    P_CH_cmd: float = 0.0  # Pa
    brake: float = 0.0  # 0..1 of the service brake
    grade: float | None = None  # rad; None: the parameter file's beta
    engine_speed_request: float | None = None  # rad/s; None: idle


@dataclass
class PlantState:
    """Everything that evolves. ``x = [omega (7), phi (5)]`` of :mod:`dsg_hil.physics.powertrain`."""

    t: float
    x: np.ndarray
    T: np.ndarray  # thermal nodes, degC, order of NODES
    P_CL: float
    P_CH: float
    governor_integral: float  # N m
    contact_torques: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])  # M_CL, M_CH, M_R friction, N m
    slip_memory: np.ndarray = field(default_factory=lambda: np.zeros(2))  # |slip| seen by (6), rad/s


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
    """Fixed-step plant. ``step(inputs)`` advances ``dt`` and returns the outputs at the new time."""

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
        self._k = (torque_per_mu(params.clutch.CL, 1.0), torque_per_mu(params.clutch.CH, 1.0))  # N m per Pa
        # Step-invariant products, so that a step costs a few small matrix-vector products. Rows of _Mx/_Mu:
        # the next state (12), the contact velocities (3), the clutch slips integrated over the step (2).
        d = self.disc
        self._Mx = np.vstack([d.Phi, d.V @ d.Phi, d.V[:2] @ d.Phi_int])
        self._Mu = np.vstack([d.Gamma, d.V @ d.Gamma, d.V[:2] @ d.Gamma_int])
        self._VG_engine, self._VG_road = (d.V @ d.Gamma[:, 0]).tolist(), (d.V @ d.Gamma[:, 3]).tolist()
        self._W = d.W_rows
        # heat_sources is affine in (Q_CL, Q_CH, P_CL, P_CH): its thermal step, evaluated once per basis input
        zero = np.zeros(len(NODES))
        self._T_const = self.thermal.step(zero, heat_sources(params, 0.0, 0.0, 0.0, 0.0))
        basis = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        self._T_src = np.column_stack([self.thermal.step(zero, heat_sources(params, *b)) - self._T_const
                                       for b in basis])
        self.state = self._initial_state(T_init, v_init)

    def _initial_state(self, T_init: float | dict[str, float], v_init: float) -> PlantState:
        pt, veh, e = self.params.powertrain, self.params.vehicle, self.params.engine
        if isinstance(T_init, dict):
            T = np.full(len(NODES), self.params.thermal.T_E)
            for name, value in T_init.items():
                if name not in NODES:
                    raise ValueError(f"unknown thermal node {name!r} (known: {', '.join(NODES)})")
                T[NODES.index(name)] = float(value)
        else:
            T = np.full(len(NODES), float(T_init))
        omega = np.zeros(N_DOF)
        omega[IDX["e"]] = omega[IDX["in"]] = e.omega_idle
        omega[IDX["1"]] = e.omega_idle / pt.i_a
        omega[IDX["5"]] = v_init / veh.r_w * pt.i_b
        omega[IDX["4"]] = omega[IDX["5"]] * pt.i_1
        omega[IDX["2"]] = omega[IDX["4"]] * pt.i_L
        omega[IDX["3"]] = omega[IDX["4"]] * pt.i_H
        x = np.concatenate([omega, np.zeros(N_SPRING)])
        state = PlantState(0.0, x, T, 0.0, 0.0, e.M_drag)
        state.slip_memory = np.abs(contact_velocities()[:2] @ x)
        return state

    def step(self, inputs: PlantInputs) -> PlantOutputs:
        p, s = self.params, self.state
        x = s.x
        T_plate = (s.T[I_CL], s.T[I_CH])
        P = (s.P_CL, s.P_CH)
        grade = p.vehicle.beta if inputs.grade is None else inputs.grade
        v = vehicle_speed(x[IDX["5"]], p.powertrain, p.vehicle)
        M_fixed, M_resist = road_load(v, grade, inputs.brake, p.vehicle)

        setpoint = p.engine.omega_idle if inputs.engine_speed_request is None else inputs.engine_speed_request
        fuel, d_integral = engine.governor(x[IDX["e"]], s.governor_integral, setpoint, p.engine)
        M_e = engine.net_torque(fuel, p.engine)

        # clutch capacities (5)-(6), mu at the remembered slip (static mu once stuck long enough)
        mu = [friction_coefficient(s.slip_memory[i] * RAD_S_TO_RPM, T_plate[i], P[i] / 1e6, p.friction)
              for i in (0, 1)]
        cap = (mu[0] * self._k[0] * P[0], mu[1] * self._k[1] * P[1], M_resist)

        # free motion, then the friction torques of the three contacts, implicitly (stick/slip)
        free = self._Mx @ x
        v_free = [float(free[N_STATE + i]) + self._VG_engine[i] * M_e + self._VG_road[i] * M_fixed for i in range(3)]
        f = solve_contacts(v_free, self._W, cap, s.contact_torques)
        y = free + self._Mu @ np.array([M_e, f[0], f[1], M_fixed + f[2]])
        x_new = y[:N_STATE]
        slip_integral = y[N_STATE + 3:].tolist()  # rad, exact over the step
        Q = [max(f[i] * slip_integral[i], 0.0) / self.dt for i in (0, 1)]  # friction heat (4), W

        # thermal network: exact step with the sources of heat_sources(Q_CL, Q_CH, P_CL, P_CH)
        T_new = self.thermal.Phi @ s.T + self._T_const + self._T_src @ np.array([Q[0], Q[1], s.P_CL, s.P_CH])
        s.x, s.T, s.contact_torques = x_new, T_new, f
        s.slip_memory = np.array([slip_memory_step(s.slip_memory[i], slip_integral[i] / self.dt, self.dt, p.friction)
                                  for i in (0, 1)])
        s.governor_integral += d_integral * self.dt
        s.P_CL = hydraulics.pressure_step(s.P_CL, inputs.P_CL_cmd, self.dt, p.hydraulics)
        s.P_CH = hydraulics.pressure_step(s.P_CH, inputs.P_CH_cmd, self.dt, p.hydraulics)
        s.t += self.dt
        stuck = [abs(f[i]) < cap[i] * (1.0 - 1e-9) for i in range(3)]
        C = self.network.C
        Q_diss = [Q[k] - C[i] * (T_new[i] - T_plate[k]) / self.dt for k, i in enumerate((I_CL, I_CH))]
        return self.outputs(M_e, mu, f, Q, stuck, Q_diss)

    def outputs(self, M_e: float = 0.0, mu: Sequence[float] = (0.0, 0.0), f: Sequence[float] = (0.0, 0.0, 0.0),
                Q: Sequence[float] = (0.0, 0.0), stuck: Sequence[bool] = (False, False, False),
                Q_diss: Sequence[float] = (0.0, 0.0)) -> PlantOutputs:
        p, s = self.params, self.state
        x, T = s.x, s.T
        return PlantOutputs(
            t=s.t, omega_e=float(x[IDX["e"]]), M_e=float(M_e), omega_in=float(x[IDX["1"]]),
            omega_CL=float(x[IDX["2"]]), omega_CH=float(x[IDX["3"]]), omega_out=float(x[IDX["5"]]),
            v=vehicle_speed(float(x[IDX["5"]]), p.powertrain, p.vehicle), P_CL=s.P_CL, P_CH=s.P_CH,
            T_oil_CL=float(T[NODES.index("CLo")]), T_oil_CH=float(T[NODES.index("CHo")]),
            T_sump=float(T[NODES.index("Fo")]), T_radiator_out=float(T[NODES.index("Ro")]),
            T_CL=float(T[I_CL]), T_CH=float(T[I_CH]), mu_CL=float(mu[0]), mu_CH=float(mu[1]),
            M_CL=float(f[0]), M_CH=float(f[1]), Q_CL=float(Q[0]), Q_CH=float(Q[1]),
            locked_CL=bool(stuck[0] and s.P_CL > 0.0), locked_CH=bool(stuck[1] and s.P_CH > 0.0),
            vehicle_held=bool(stuck[2]), Q_diss_CL=float(Q_diss[0]), Q_diss_CH=float(Q_diss[1]))
