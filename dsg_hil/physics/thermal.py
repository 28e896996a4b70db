"""Lumped thermal network of the gearbox cooling system, equations (1)-(4).

Each element i of Fig. 2 (F, P, RV, V, CL, CH, R) has a component node ``i`` and an oil node ``i_o`` as in (2);
the environment E is a fixed-temperature boundary. Conductances join nodes both ways (K_ij (T_i - T_j));
the oil circuit reservoir F -> pump P -> valve V (relief RV -> F) -> clutches CL, CH -> radiator R -> F carries
heat downstream only (m_dot c_p (T_upstream - T_i)), which conserves energy around the closed loop. Each clutch
has its own pack (capacity, friction surfaces) and its own cooling flow (``thermal.clutch.CL/CH.Q_cool``); the
valve's remaining flow bypasses the clutches to R. The Section III.C rig is the same network with the test clutch
in slot CL (:func:`dsg_hil.physics.rig.rig_configuration`).

In matrix form: ``C dT/dt = -L T + g_E T_E + q``. With ``q`` held over a step this is linear with constant
coefficients, so :func:`discretize` gives its exact solution (matrix exponential).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

from .params import ClutchGeometry, ClutchThermal, Element, Params

__all__ = ["DiscreteNetwork", "ELEMENTS", "NODES", "Network", "NetworkBuilder", "clutch_element", "discretize",
           "gearbox_network", "heat_sources", "zoh"]

ELEMENTS = ("F", "P", "RV", "V", "CL", "CH", "R")
NODES = tuple(n for e in ELEMENTS for n in (e, e + "o"))
_I = {name: i for i, name in enumerate(NODES)}


@dataclass(frozen=True)
class Network:
    """A linear thermal network: capacities C [J/K], operator L [W/K], conductances to E g_E [W/K]."""

    names: tuple[str, ...]
    C: np.ndarray
    L: np.ndarray
    g_E: np.ndarray
    T_E: float

    def derivative(self, T: np.ndarray, q: np.ndarray) -> np.ndarray:
        """dT/dt [K/s] for node temperatures T [degC] and heat sources q [W]."""
        return (-self.L @ T + self.g_E * self.T_E + q) / self.C

    def heat_to_environment(self, T: np.ndarray) -> float:
        """Heat flow leaving the network to E [W]."""
        return float(self.g_E @ (T - self.T_E))


class NetworkBuilder:
    """Collects nodes and edges, then builds a :class:`Network`."""

    def __init__(self, names: tuple[str, ...], T_E: float) -> None:
        self.names = names
        self.T_E = T_E
        n = len(names)
        self.C = np.zeros(n)
        self.L = np.zeros((n, n))
        self.g_E = np.zeros(n)

    def capacity(self, node: str, C: float) -> None:
        self.C[self.names.index(node)] = C

    def conductance(self, a: str, b: str, K: float) -> None:
        """Two-way exchange K (T_a - T_b) [W/K]; b = "E" is the environment."""
        i = self.names.index(a)
        if b == "E":
            self.g_E[i] += K
            self.L[i, i] += K
            return
        j = self.names.index(b)
        self.L[i, i] += K
        self.L[j, j] += K
        self.L[i, j] -= K
        self.L[j, i] -= K

    def flow(self, upstream: str, downstream: str, W: float) -> None:
        """Oil flow carrying heat from upstream to downstream, W = m_dot c_p [W/K]."""
        i, j = self.names.index(upstream), self.names.index(downstream)
        self.L[j, j] += W
        self.L[j, i] -= W

    def build(self) -> Network:
        if np.any(self.C <= 0.0):
            missing = [n for n, c in zip(self.names, self.C) if c <= 0.0]
            raise ValueError(f"thermal nodes without capacity: {missing}")
        return Network(self.names, self.C.copy(), self.L.copy(), self.g_E.copy(), self.T_E)


def clutch_element(geometry: ClutchGeometry, thermal: ClutchThermal) -> Element:
    """Element CL or CH of (3): plate pack, its oil, and K_CL,CLo = h N pi (R_o^2 - R_i^2)."""
    wetted = geometry.N * np.pi * (geometry.R_o**2 - geometry.R_i**2)
    return Element(C=geometry.C_plate, V_o=thermal.V_o, K_io=thermal.h_plate_oil * wetted, K_iE=thermal.K_iE,
                   K_oE=thermal.K_oE)


def gearbox_network(params: Params) -> Network:
    """The network of Fig. 2 with the circuit's oil flows, for the clutches params.clutch.CL/CH."""
    th, c, oil = params.thermal, params.circuit, params.oil
    elements = {
        "F": th.F, "P": th.P, "RV": th.RV, "V": th.V, "R": th.R,
        "CL": clutch_element(params.clutch.CL, th.clutch.CL),
        "CH": clutch_element(params.clutch.CH, th.clutch.CH),
    }
    b = NetworkBuilder(NODES, th.T_E)
    for name, e in elements.items():
        o = name + "o"
        b.capacity(name, e.C)
        b.capacity(o, oil.rho * oil.c_p * e.V_o)
        b.conductance(name, o, e.K_io)
        b.conductance(name, "E", e.K_iE)
        b.conductance(o, "E", e.K_oE)
    W = oil.rho * oil.c_p  # J/(m^3 K)
    Q_valve = c.Q_pump - c.Q_relief
    Q_CL, Q_CH = th.clutch.CL.Q_cool, th.clutch.CH.Q_cool
    b.flow("Fo", "Po", W * c.Q_pump)
    b.flow("Po", "RVo", W * c.Q_relief)
    b.flow("RVo", "Fo", W * c.Q_relief)
    b.flow("Po", "Vo", W * Q_valve)
    b.flow("Vo", "CLo", W * Q_CL)
    b.flow("Vo", "CHo", W * Q_CH)
    b.flow("Vo", "Ro", W * (Q_valve - Q_CL - Q_CH))
    b.flow("CLo", "Ro", W * Q_CL)
    b.flow("CHo", "Ro", W * Q_CH)
    b.flow("Ro", "Fo", W * Q_valve)
    return b.build()


def heat_sources(params: Params, Q_CL: float, Q_CH: float, P_CL: float, P_CH: float) -> np.ndarray:
    """Source vector q [W] over NODES, equation (4) and the hydraulics.

    Q_CL, Q_CH: friction heat M * delta_omega into the plates [W]. Throttle losses q_r * delta_p into the clutch oil,
    with q_r the cooling flow and delta_p the clutch pressure P_CL/P_CH [Pa]; the rest of the pump's hydraulic power
    is throttled in V and RV, and the pump's own losses heat its oil, so the circuit turns all pump power into heat.
    """
    c, cool = params.circuit, params.thermal.clutch
    q = np.zeros(len(NODES))
    throttle_CL = cool.CL.Q_cool * max(P_CL, 0.0)
    throttle_CH = cool.CH.Q_cool * max(P_CH, 0.0)
    hydraulic = c.Q_pump * c.p_line
    q[_I["CL"]] = Q_CL
    q[_I["CH"]] = Q_CH
    q[_I["CLo"]] = throttle_CL
    q[_I["CHo"]] = throttle_CH
    q[_I["Po"]] = hydraulic * (1.0 / c.eta_pump - 1.0)
    q[_I["RVo"]] = c.Q_relief * c.p_line
    q[_I["Vo"]] = (c.Q_pump - c.Q_relief) * c.p_line - throttle_CL - throttle_CH
    return q


@dataclass(frozen=True)
class DiscreteNetwork:
    """Exact zero-order-hold step of a network: T[k+1] = Phi T[k] + Gamma (g_E T_E + q[k]) / C."""

    network: Network
    dt: float
    Phi: np.ndarray
    Gamma: np.ndarray
    _Gamma_per_C: np.ndarray = field(init=False, repr=False, compare=False)  # set in __post_init__
    _drive: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        n = self.network
        object.__setattr__(self, "_Gamma_per_C", self.Gamma / n.C[None, :])
        object.__setattr__(self, "_drive", self.Gamma @ (n.g_E * n.T_E / n.C))

    def step(self, T: np.ndarray, q: np.ndarray) -> np.ndarray:
        return self.Phi @ T + self._drive + self._Gamma_per_C @ q


def zoh(A: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretization of x' = A x + u with u held over dt: returns (e^{A dt}, int_0^dt e^{A s} ds)."""
    n = A.shape[0]
    aug = np.zeros((2 * n, 2 * n))
    aug[:n, :n] = A
    aug[:n, n:] = np.eye(n)
    E = expm(aug * dt)
    return E[:n, :n], E[:n, n:]


def discretize(network: Network, dt: float) -> DiscreteNetwork:
    if not dt > 0.0:
        raise ValueError(f"dt must be positive, got {dt}")
    Phi, Gamma = zoh(-network.L / network.C[:, None], dt)
    return DiscreteNetwork(network, dt, Phi, Gamma)
