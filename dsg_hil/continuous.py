"""The plant's equations in continuous time, for checking the fixed-step plant against a tight-tolerance
``scipy.integrate.solve_ivp`` solution. Valid while both clutches slip and the vehicle rolls (no mode changes):
the same physics functions as :mod:`dsg_hil.plant`, evaluated continuously instead of held over a step.

State ``y = [omega (7), phi (5), T (14 nodes), P_CL, P_CH, governor integral, slip memory CL, CH]``.
"""

from __future__ import annotations

import math

import numpy as np

from .physics import engine
from .physics.friction import RAD_S_TO_RPM, friction_coefficient, torque_per_mu
from .physics.powertrain import IDX, N_DOF, N_STATE, road_load, vehicle_speed
from .physics.hydraulics import clamp_command
from .physics.thermal import NODES, heat_sources
from .plant import Plant, PlantInputs

N_T = len(NODES)


def pack(plant: Plant) -> np.ndarray:
    s = plant.state
    return np.concatenate([s.x, s.T, [s.P_CL, s.P_CH, s.governor_integral], s.slip_memory])


def rhs(plant: Plant, inputs: PlantInputs):
    """f(t, y) for solve_ivp, with the inputs held constant."""
    p = plant.params
    grade = p.vehicle.beta if inputs.grade is None else inputs.grade
    setpoint = p.engine.omega_idle if inputs.engine_speed_request is None else inputs.engine_speed_request
    k_CL, k_CH = torque_per_mu(p.clutch.CL, 1.0), torque_per_mu(p.clutch.CH, 1.0)
    i_CL, i_CH = NODES.index("CL"), NODES.index("CH")

    def f(t: float, y: np.ndarray) -> np.ndarray:
        x, T = y[:N_STATE], y[N_STATE:N_STATE + N_T]
        P_CL, P_CH, integral, mem_CL, mem_CH = y[N_STATE + N_T:]
        slip_CL, slip_CH = x[IDX["1"]] - x[IDX["2"]], x[IDX["1"]] - x[IDX["3"]]
        mu_CL = friction_coefficient(mem_CL * RAD_S_TO_RPM, T[i_CL], P_CL / 1e6, p.friction)
        mu_CH = friction_coefficient(mem_CH * RAD_S_TO_RPM, T[i_CH], P_CH / 1e6, p.friction)
        M_CL = math.copysign(mu_CL * k_CL * P_CL, slip_CL)
        M_CH = math.copysign(mu_CH * k_CH * P_CH, slip_CH)
        v = vehicle_speed(x[IDX["5"]], p.powertrain.i_b, p.vehicle.r_w)
        M_fixed, M_resist = road_load(v, grade, inputs.brake, p.vehicle)
        fuel, d_integral = engine.governor(x[IDX["e"]], integral, setpoint, p.engine)
        u = np.array([engine.net_torque(fuel, p.engine), M_CL, M_CH, M_fixed + math.copysign(M_resist, v)])
        q = heat_sources(p, abs(M_CL * slip_CL), abs(M_CH * slip_CH), P_CL, P_CH)
        tau = p.hydraulics.tau
        return np.concatenate([
            plant.model.derivative(x, u),
            plant.network.derivative(T, q),
            [(clamp_command(inputs.P_CL_cmd, p.hydraulics) - P_CL) / tau,
             (clamp_command(inputs.P_CH_cmd, p.hydraulics) - P_CH) / tau, d_integral,
             (abs(slip_CL) - mem_CL) / p.friction.tau_slip, (abs(slip_CH) - mem_CH) / p.friction.tau_slip],
        ])

    return f


__all__ = ["N_DOF", "N_STATE", "N_T", "pack", "rhs"]
