"""The plant: assembles engine, hydraulics, both wet clutches, the thermal network and the powertrain, and steps
them at a fixed step (1 ms by default). Deterministic: no clocks, no randomness, no I/O.

Each step (inputs held over it, zero-order hold):

1. engine (governor), the clutch capacities (5)-(6) at the present slip, temperature and pressure, and the road
   load (13) give the torques and friction limits (at standstill the vehicle is held only up to its breakaway
   resistance plus brake, :func:`dsg_hil.physics.powertrain.holding_torque`);
2. the torsional model takes its exact step; the friction torques of both clutches and of the vehicle's rolling
   resistance plus brake are solved implicitly, so a clutch whose slip would cross zero locks if it can carry
   the torque, and slips again when it cannot (:func:`dsg_hil.physics.powertrain.solve_contacts`);
3. the friction heat (4), M times the exact integral of the slip over the step, and the hydraulic losses drive
   the exact step of the thermal network; the pressures take their exact first-order step.

The contact law a 1-ms step can carry: stick/slip of a clutch is decided on its MEAN slip over the
step, ``V (Phi_int x + Gamma_int u) / dt`` (exact, linear in the torques as the end velocity is), so a locked
clutch does no work and a slipping one dissipates exactly |M| times its slip integral: the energy closes at any
step. The vehicle's is decided on its speed at the step's END, so a held vehicle ends every step at rest (on its
mean speed it ended each step moving the other way, an undamped ringing at the Nyquist frequency read as
roll-back; :func:`dsg_hil.physics.powertrain.law_rows`); its brake's work is not heat of the network. mu (6) is
evaluated at the slip memory half a step on (predicted with the slips at the step's start) and
the capacities (5) at each pressure's exact mean over the step: neither lags the motion by half a step, which
would take damping out of the lightly damped driveline modes (the 88-Hz mode of the held vehicle). A step in which
a contact changes mode (or a slipping one's velocity crosses zero) is taken again in :data:`N_SUB` sub-steps, and
a step with a clutch locked in :data:`N_LOCKED` (the mean law leaves a locked pair's stiffest modes ringing within
a 1-ms step), so the step study (``bench/plant_speed.py``) keeps the speeds within 2 % of full scale at 1 ms;
``bench/contact_law.py`` compares the laws with the continuous model (:mod:`dsg_hil.physics.continuous`).

The steps run compiled (:func:`advance_steps`, numba through :mod:`dsg_hil.physics.jit`), many per call: the
state (with the outputs and the kernel's working arrays) is one float64 array, the step-invariant matrices and
parameters one record (:func:`dsg_hil.physics.jit.constants`), and :meth:`Plant.advance` takes a whole control
period in one call and returns the outputs at its end (plus the period's peak plate temperatures and friction
energy, :attr:`Plant.period`). :meth:`Plant.step` is one step of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .engine import governor, net_torque
from .friction import (
    friction_coefficient_at,
    pressure_factors,
    slip_memory_relax,
    torque_per_mu,
)
from .hydraulics import clamp_command, pressure_relax
from .jit import compiled, constants
from .params import Params
from .powertrain import (
    IDX,
    N_DOF,
    N_SPRING,
    N_STATE,
    Discrete,
    Model,
    build_model,
    holding_torque,
    road_load,
    solve_contacts_into,
    vehicle_speed,
)
from .powertrain import discretize as discretize_powertrain
from .thermal import NODES, gearbox_network, heat_sources
from .thermal import discretize as discretize_network

__all__ = ["I_CH", "I_CL", "N_LOCKED", "N_OUT", "N_S", "N_SUB", "N_T", "PERIOD", "Plant", "PlantInputs", "PlantOutputs",
           "PlantState", "S_F", "S_GOV", "S_K", "S_MEM", "S_P", "S_T", "S_TEMP", "S_X", "add_products", "advance_steps",
           "contact_step", "modes_of", "outputs_of", "sub_steps", "write_outputs"]

I_CL, I_CH = NODES.index("CL"), NODES.index("CH")
N_T = len(NODES)

# The state as one float64 array: t [s], the step count k (a whole number, exact in a float64 up to 2**53), x =
# [omega (7), phi (5)], T (thermal nodes, degC, order of NODES), P_CL, P_CH [Pa], governor integral [N m], contact
# torques M_CL, M_CH, M_R [N m], slip memory of CL, CH [rad/s]. t is derived from k (see Plant), never summed.
S_T, S_K, S_X = 0, 1, 2
S_TEMP = S_X + N_STATE
S_P = S_TEMP + N_T
S_GOV = S_P + 2
S_F = S_GOV + 1
S_MEM = S_F + 3
N_S = S_MEM + 2
# Outputs at the end of a step, in the order of PlantOutputs' fields (bool fields as 0.0 / 1.0).
N_OUT = 28
_O_LOCKED = 22
# The period's extremes and sums (Plant.period): peak plate temperatures [degC], friction energy [J].
PERIOD = ("T_CL_max", "T_CH_max", "E_CL", "E_CH")
# The plant's array: the state, then the outputs, then the period's (compiled code reads and writes it in place)
_N_ROWS = N_STATE + 3  # rows of _Mx, _Mu: the next state, the contact law's velocities (3: powertrain.law_rows)
_N_ROWS_4, _N_T_4 = -(-_N_ROWS // 4) * 4, -(-N_T // 4) * 4  # in fours (add_products)
# The plant's array: the state, the outputs, the period's, then the kernel's working arrays (so that a call
# allocates nothing): free motion and contact velocities, new temperatures, v_free, cap, limit, f, torques, sources.
_B_OUT = N_S
_B_PERIOD = _B_OUT + N_OUT
_B_FREE = _B_PERIOD + len(PERIOD)
_B_T_NEW = _B_FREE + _N_ROWS_4
_B_V_FREE = _B_T_NEW + _N_T_4
_B_CAP = _B_V_FREE + 3
_B_LIMIT = _B_CAP + 3
_B_F = _B_LIMIT + 3
_B_TORQUES = _B_F + 3
_B_SOURCES = _B_TORQUES + 4
_B_STUCK = _B_SOURCES + 4  # the contacts' modes after the last step (1 stuck, 0 slipping, -1 none yet)
_B_SUB = _B_STUCK + 3  # a sub-stepped step's x and slip memories
_N_B = _B_SUB + N_STATE + 2
N_SUB = 10  # sub-steps of a step in which a contact changes mode
N_LOCKED = 2  # sub-steps of a step with a clutch locked


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
    def t(self) -> float:  # s, k dt_ns / 1e9 (Plant)
        return float(self.array[S_T])

    @property
    def k(self) -> int:  # steps taken
        return int(self.array[S_K])

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
    a_x: float = 0.0  # longitudinal accelerometer (as from the ESC), m/s^2: dv/dt over the step + g sin(grade)


class Plant:
    """Fixed-step plant. ``advance(inputs, n)`` takes n steps of ``dt`` in one compiled call, ``step(inputs)`` one;
    both return the outputs at the new time.

    Time is counted, not summed: the plant counts its steps ``k`` and its time is ``t = k dt_ns / 1e9`` [s], the
    exact time (an integer number of nanoseconds) rounded once to a float. So t does not drift from k dt (a float
    sum of dt does), and a whole number of milliseconds (the DBC's cycle times) or of nanoseconds is the very float
    its decimal literal gives (a time from a scenario file compares exactly)."""

    def __init__(self, params: Params, dt: float = 1e-3, T_init: float | dict[str, float] = 25.0,
                 v_init: float = 0.0) -> None:
        if not dt > 0.0:
            raise ValueError(f"dt must be positive, got {dt}")
        dt_ns = round(dt * 1e9)
        if dt_ns < 1 or abs(dt * 1e9 - dt_ns) > 1e-3:  # the caller's float dt: a whole number of ns, to 1 ps
            raise ValueError(f"dt must be a whole number of nanoseconds, got {dt}")
        self.params = params
        self.dt = dt
        self.dt_ns = dt_ns
        self.model: Model = build_model(params.powertrain, params.vehicle)
        self.disc: Discrete = discretize_powertrain(self.model, dt)
        self.network = gearbox_network(params)
        self.thermal = discretize_network(self.network, dt)
        # Step-invariant products, so that a step costs a few small matrix-vector products. Rows of _Mx/_Mu:
        # the next state (12), the contact velocities' means over the step (3; the slips' integrals / dt).
        d = self.disc
        self._Mx, self._Mu = _step_rows(d)
        # sub-steps: of a step in which a contact changes mode (sub), of one with a clutch locked (lock)
        d_sub, d_lock = discretize_powertrain(self.model, dt / N_SUB), discretize_powertrain(self.model, dt / N_LOCKED)
        rows_sub, rows_lock = _step_rows(d_sub), _step_rows(d_lock)
        # heat_sources is affine in (Q_CL, Q_CH, P_CL, P_CH): its thermal step, evaluated once per basis input
        zero = np.zeros(N_T)
        self._T_const = self.thermal.step(zero, heat_sources(params, 0.0, 0.0, 0.0, 0.0))
        basis = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        self._T_src = np.column_stack(
            [self.thermal.step(zero, heat_sources(params, *b)) - self._T_const for b in basis])
        C = self.network.C
        # All the kernel's constants as one record (jit.constants); the matrices blocked by fours (add_products)
        self._K = constants({
            "MxT": _blocked(self._Mx), "MuT": _blocked(self._Mu),
            "VG": _drive_rows(d), "W": d.W,
            "MxS_T": _blocked(rows_sub[0]), "MuS_T": _blocked(rows_sub[1]), "VGS": _drive_rows(d_sub), "WS": d_sub.W,
            "MxL_T": _blocked(rows_lock[0]), "MuL_T": _blocked(rows_lock[1]), "VGL": _drive_rows(d_lock),
            "WL": d_lock.W,
            "PhiT_T": _blocked(self.thermal.Phi), "T_const": self._T_const, "T_srcT": _blocked(self._T_src),
            "k_CL": torque_per_mu(params.clutch.CL, 1.0), "k_CH": torque_per_mu(params.clutch.CH, 1.0),  # N m/Pa (5)
            "C_CL": C[I_CL], "C_CH": C[I_CH], "i_b": params.powertrain.i_b,  # plate capacities [J/K]
            "dt": dt, "dt_ns": float(dt_ns),  # step [s], and in whole ns (the time: k dt_ns / 1e9)
            # contact velocity from which a slipping contact's torque is its limit (the vehicle's, powertrain)
            "v_ramp": np.array([1.0, 1.0, params.vehicle.v_stick / params.vehicle.r_w * params.powertrain.i_b]),
        }, params.friction, params.engine, params.hydraulics, params.vehicle)
        # the plant's array: state (N_S), outputs of the last step, the period's peaks and sums, working arrays
        self._b = np.zeros(_N_B)
        self._b[_B_STUCK:_B_STUCK + 3] = -1.0
        self._s = self._b[:N_S]
        self._s[:] = self._initial_state(T_init, v_init)
        self.state = PlantState(self._s)
        self._out = self._b[_B_OUT:_B_OUT + N_OUT]
        self.period = self._b[_B_PERIOD:_B_PERIOD + len(PERIOD)]  # of the last advance, see PERIOD
        self._no_trace = np.zeros((0, N_OUT))
        self._steps = advance_steps.specialize(self._b, self._K, self._no_trace, 0.0, 0.0, 0.0, 0.0, 0.0, 0)
        # before the first step: at rest on the parameter file's grade (the accelerometer reads its gradient)
        v_0 = vehicle_speed(self._s[S_X + _5], params.powertrain.i_b, params.vehicle.r_w)
        write_outputs(self._b, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, params.powertrain.i_b,
                      params.vehicle.r_w, v_0, params.vehicle.g * math.sin(params.vehicle.beta), self._K[0]["dt"])
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
        if trace is None:
            trace = self._no_trace
        elif trace.shape != (n_steps, N_OUT) or trace.dtype != np.float64 or not trace.flags.c_contiguous:
            raise ValueError(f"trace must be a C-contiguous float64 array of shape {(n_steps, N_OUT)}")
        grade, request = inputs.grade, inputs.engine_speed_request
        last = self._steps(self._b, self._K, trace, inputs.P_CL_cmd, inputs.P_CH_cmd, inputs.brake,
                    self.params.vehicle.beta if grade is None else grade,
                    self.params.engine.omega_idle if request is None else request, n_steps)
        self._last = _make_outputs(last)
        return self._last

    def step(self, inputs: PlantInputs) -> PlantOutputs:
        """One step of ``dt``."""
        return self.advance(inputs, 1)

    def outputs(self) -> PlantOutputs:
        """The outputs at the present time (after the last step; before any, with no torque flowing)."""
        return self._last

    def snapshot(self) -> np.ndarray:
        """The plant's whole array (a copy): the state, the last outputs, the period's, the contacts' modes and the
        working arrays, everything a step reads; :meth:`restore` of it replays the steps after it to the bit."""
        return self._b.copy()

    def restore(self, snapshot: np.ndarray) -> None:
        """Back to a :meth:`snapshot` of a plant with the same parameters."""
        if snapshot.shape != self._b.shape:
            raise ValueError(f"a plant snapshot has {self._b.size} values, not {snapshot.size}")
        self._b[:] = snapshot
        self._last = self.sample(self._out)

    @staticmethod
    def sample(row: np.ndarray) -> PlantOutputs:
        """The outputs of a row of :meth:`advance`'s ``trace``."""
        v = row.tolist()
        v[_O_LOCKED] = v[_O_LOCKED] != 0.0
        v[_O_LOCKED + 1] = v[_O_LOCKED + 1] != 0.0
        v[_O_LOCKED + 2] = v[_O_LOCKED + 2] != 0.0
        return _make_outputs(v)


_make_outputs = PlantOutputs._make


def _step_rows(d: Discrete) -> tuple[np.ndarray, np.ndarray]:
    """(Mx, Mu): rows of the next state (12) and of the velocities the contact law acts on (3: the clutches' mean
    slips, the vehicle's end speed; :func:`dsg_hil.physics.powertrain.law_rows`)."""
    return (np.ascontiguousarray(np.vstack([d.Phi, d.L_x])), np.ascontiguousarray(np.vstack([d.Gamma, d.L_u])))


def _drive_rows(d: Discrete) -> np.ndarray:
    """The contact law's velocities' response to the engine torque and to the fixed road load (rows)."""
    return np.vstack([d.L_u[:, 0], d.L_u[:, 3]])


@compiled
def outputs_of(b):
    """The outputs in the plant's array b as the values of :class:`PlantOutputs` (the flags as bool): returned to
    Python as one tuple, built by compiled code (cheaper than reading the array from Python)."""
    o = b[_B_OUT:_B_OUT + N_OUT]
    return (o[0], o[1], o[2], o[3], o[4], o[5], o[6], o[7], o[8], o[9], o[10], o[11], o[12], o[13], o[14], o[15],
            o[16], o[17], o[18], o[19], o[20], o[21], o[22] != 0.0, o[23] != 0.0, o[24] != 0.0, o[25], o[26],
            o[27])


@compiled
def write_outputs(b, M_e, mu_CL, mu_CH, M_CL, M_CH, Q_CL, Q_CH, stuck_CL, stuck_CH, held, Q_diss_CL, Q_diss_CH,
                  i_b, r_w, v_start, g_sin_grade, dt):
    """The outputs (:class:`PlantOutputs`' fields in order) from the state and the step's torques and heat: the
    state at the start of the plant's array b, the outputs written at _B_OUT. The accelerometer reads the step's
    mean acceleration (the speed's change from ``v_start`` over ``dt``) plus the gradient's ``g sin(grade)``: what
    a body-fixed sensor measures along the vehicle (a standing vehicle reads the grade)."""
    o = _B_OUT
    b[o] = b[S_T]
    b[o + 1] = b[S_X + _E]
    b[o + 2] = M_e
    b[o + 3] = b[S_X + _1]
    b[o + 4] = b[S_X + _2]
    b[o + 5] = b[S_X + _3]
    b[o + 6] = b[S_X + _5]
    b[o + 7] = vehicle_speed(b[S_X + _5], i_b, r_w)
    b[o + 8] = b[S_P]
    b[o + 9] = b[S_P + 1]
    b[o + 10] = b[S_TEMP + _I_CLO]
    b[o + 11] = b[S_TEMP + _I_CHO]
    b[o + 12] = b[S_TEMP + _I_FO]
    b[o + 13] = b[S_TEMP + _I_RO]
    b[o + 14] = b[S_TEMP + I_CL]
    b[o + 15] = b[S_TEMP + I_CH]
    b[o + 16] = mu_CL
    b[o + 17] = mu_CH
    b[o + 18] = M_CL
    b[o + 19] = M_CH
    b[o + 20] = Q_CL
    b[o + 21] = Q_CH
    b[o + 22] = 1.0 if stuck_CL != 0.0 and b[S_P] > 0.0 else 0.0
    b[o + 23] = 1.0 if stuck_CH != 0.0 and b[S_P + 1] > 0.0 else 0.0
    b[o + 24] = held
    b[o + 25] = Q_diss_CL
    b[o + 26] = Q_diss_CH
    b[o + 27] = (b[o + 7] - v_start) / dt + g_sin_grade


_I_CLO, _I_CHO, _I_FO, _I_RO = (NODES.index(n) for n in ("CLo", "CHo", "Fo", "Ro"))
_E, _1, _2, _3, _5 = (IDX[n] for n in ("e", "1", "2", "3", "5"))  # speeds as plain ints, for compiled code


@compiled
def add_products(acc, M_T, v, at):
    """``acc[i] += M_T[j, i] * v[at + j]`` over the rows j of M_T in order: each acc[i] the sum a loop over j gives,
    bit for bit, but four i at a time in registers (independent chains of additions, which the compiler packs into
    vector instructions). acc is kept by fours, acc[block, lane] for i = 4 block + lane, and M_T as
    M_T[block, j, lane] (:func:`_blocked`)."""
    for block in range(M_T.shape[0]):
        a0, a1, a2, a3 = acc[block, 0], acc[block, 1], acc[block, 2], acc[block, 3]
        for j in range(M_T.shape[1]):
            v_j = v[at + j]
            a0 += M_T[block, j, 0] * v_j
            a1 += M_T[block, j, 1] * v_j
            a2 += M_T[block, j, 2] * v_j
            a3 += M_T[block, j, 3] * v_j
        acc[block, 0], acc[block, 1], acc[block, 2], acc[block, 3] = a0, a1, a2, a3


def _blocked(M: np.ndarray) -> np.ndarray:
    """M (rows x columns) as M_T[block, column, lane] = M[4 block + lane, column] (zero rows added up to a
    multiple of 4), for :func:`add_products`."""
    rows = -(-M.shape[0] // 4) * 4
    padded = np.vstack([M, np.zeros((rows - M.shape[0], M.shape[1]))])
    return np.ascontiguousarray(padded.reshape(rows // 4, 4, M.shape[1]).transpose(0, 2, 1))


@compiled
def contact_step(b, x_at, mem_at, Mx_T, Mu_T, VG, W, v_ramp, M_e, M_fixed, M_hold, M_resist, k_P_CL, k_P_CH,
                 T_CL, T_CH, factor_CL, log_CL, factor_CH, log_CH, decay_half, k):
    """The torsional model's step from the state x at ``b[x_at:]`` with the slip memories at ``b[mem_at:]``
    (module docstring): the friction torques of the three contacts solved on the law's velocities (starting from
    the torques in the working array f), mu at mid-step, then the next state and the law's velocities into
    the working array ``free`` (rows of Mx_T/Mu_T). Returns (mu_CL, mu_CH); cap and f hold the contacts' last
    capacities and torques."""
    free = b[_B_FREE:_B_FREE + _N_ROWS_4]
    free_by_4 = free.reshape((_N_ROWS_4 // 4, 4))  # the same numbers as add_products keeps them
    v_free, cap, f = b[_B_V_FREE:_B_V_FREE + 3], b[_B_CAP:_B_CAP + 3], b[_B_F:_B_F + 3]
    limit, torques = b[_B_LIMIT:_B_LIMIT + 3], b[_B_TORQUES:_B_TORQUES + 4]
    # mu at the slip memory half a step on, predicted with the present slips (the lag of a step's start would
    # take damping out of the driveline modes; the prediction's error is second order in dt)
    mem_CL = slip_memory_relax(b[mem_at], b[x_at + _1] - b[x_at + _2], decay_half)
    mem_CH = slip_memory_relax(b[mem_at + 1], b[x_at + _1] - b[x_at + _3], decay_half)
    mu_CL = friction_coefficient_at(mem_CL, T_CL, factor_CL, log_CL, k)
    mu_CH = friction_coefficient_at(mem_CH, T_CH, factor_CH, log_CH, k)
    cap[0], cap[1], cap[2] = mu_CL * k_P_CL, mu_CH * k_P_CH, M_hold
    limit[0], limit[1], limit[2] = cap[0], cap[1], M_resist  # the clutches: Coulomb friction
    # free motion, then the friction torques of the three contacts, implicitly (stick/slip on the clutches' mean
    # slips and the vehicle's end speed, powertrain.law_rows)
    free[:] = 0.0
    add_products(free_by_4, Mx_T, b, x_at)
    for i in range(3):
        v_free[i] = free[N_STATE + i] + VG[0, i] * M_e + VG[1, i] * M_fixed
    solve_contacts_into(v_free, W, cap, limit, v_ramp, f)
    torques[0], torques[1], torques[2], torques[3] = M_e, f[0], f[1], M_fixed + f[2]
    add_products(free_by_4, Mu_T, torques, 0)
    return mu_CL, mu_CH


@compiled
def modes_of(b):
    """Writes each contact's mode after a solve (1.0 stuck, 0.0 slipping) into the working array ``stuck``;
    returns True if any differs from what it held (the last step's modes; -1 before the first step) or a slipping
    one ends the step moving against its friction torque (its velocity crossed zero within the step: it would
    have stuck or turned there). The next state is in the working array ``free``."""
    cap, f, stuck, free = b[_B_CAP:_B_CAP + 3], b[_B_F:_B_F + 3], b[_B_STUCK:_B_STUCK + 3], b[_B_FREE:_B_FREE + 7]
    changed = False
    for i in range(3):
        mode = 1.0 if abs(f[i]) < cap[i] * (1.0 - 1e-9) else 0.0
        changed = changed or (stuck[i] >= 0.0 and mode != stuck[i])
        stuck[i] = mode
    v_end_CL, v_end_CH = free[_1] - free[_2], free[_1] - free[_3]
    return (changed or (stuck[0] == 0.0 and f[0] * v_end_CL < 0.0) or (stuck[1] == 0.0 and f[1] * v_end_CH < 0.0)
            or (stuck[2] == 0.0 and f[2] * free[_5] < 0.0))


@compiled
def sub_steps(b, n, Mx_T, Mu_T, VG, W, M_e, M_fixed, M_hold, M_resist, k_P_CL, k_P_CH, T_CL, T_CH, factor_CL,
              log_CL, factor_CH, log_CH, k):
    """The torsional model's step from the state in b again as ``n`` sub-steps (matrices of dt / n; the torques,
    capacities' pressures and plate temperatures of the step), x and the slip memories updated in b. Returns the
    friction heat (4) of both clutches [W] (the step's means) and mu of the last sub-step."""
    dt_sub = k.dt / n
    decay, decay_half = math.exp(-dt_sub / k.tau_slip), math.exp(-0.5 * dt_sub / k.tau_slip)
    free, f = b[_B_FREE:_B_FREE + _N_ROWS_4], b[_B_F:_B_F + 3]
    sub = b[_B_SUB:_B_SUB + N_STATE + 2]  # x, then the slip memories
    for i in range(N_STATE):
        sub[i] = b[S_X + i]
    sub[N_STATE], sub[N_STATE + 1] = b[S_MEM], b[S_MEM + 1]
    f[0], f[1], f[2] = b[S_F], b[S_F + 1], b[S_F + 2]
    work_CL = work_CH = mu_CL = mu_CH = 0.0
    for _ in range(n):
        mu_CL, mu_CH = contact_step(b, _B_SUB, _B_SUB + N_STATE, Mx_T, Mu_T, VG, W, k.v_ramp, M_e, M_fixed, M_hold,
                                    M_resist, k_P_CL, k_P_CH, T_CL, T_CH, factor_CL, log_CL, factor_CH, log_CH,
                                    decay_half, k)
        modes_of(b)  # (the modes after the last sub-step are the step's)
        work_CL += max(f[0] * free[N_STATE], 0.0) * dt_sub
        work_CH += max(f[1] * free[N_STATE + 1], 0.0) * dt_sub
        for i in range(N_STATE):
            sub[i] = free[i]
        sub[N_STATE] = slip_memory_relax(sub[N_STATE], free[N_STATE], decay)
        sub[N_STATE + 1] = slip_memory_relax(sub[N_STATE + 1], free[N_STATE + 1], decay)
    for i in range(N_STATE):
        b[S_X + i] = sub[i]
    b[S_MEM], b[S_MEM + 1] = sub[N_STATE], sub[N_STATE + 1]
    return work_CL / k.dt, work_CH / k.dt, mu_CL, mu_CH


@compiled
def advance_steps(b, K, trace, P_CL_cmd, P_CH_cmd, brake, grade, setpoint, n_steps):
    """``n_steps`` plant steps (module docstring) with the inputs held (pressure commands [Pa], brake 0..1, grade
    [rad], engine speed setpoint [rad/s]) on the plant's array b in place: its state, then the outputs of the last
    step (at _B_OUT), the period's peaks and sums (at _B_PERIOD) and the working arrays; K: the plant's constants
    (jit.constants), one record. If ``trace`` has rows, each step's outputs are written to them. Returns the outputs
    at the end (:func:`outputs_of`).

    A step in which a contact changes mode (a clutch locks or lets go, the vehicle is held or starts to roll) is
    taken again as :data:`N_SUB` sub-steps, one with a clutch locked as :data:`N_LOCKED` (:func:`sub_steps`).

    The matrix-vector products run column by column: each row's sum is taken in the same order as a row-by-row
    loop (the same result bit for bit), but the rows' sums are independent and run side by side instead of as one
    long chain of additions, each waiting for the last. The step allocates nothing and takes no array views."""
    k = K[0]
    Mx_T, Mu_T, VG, W, PhiT_T, T_const, T_srcT = k.MxT, k.MuT, k.VG, k.W, k.PhiT_T, k.T_const, k.T_srcT
    dt, dt_ns, i_b = k.dt, k.dt_ns, k.i_b
    free = b[_B_FREE:_B_FREE + _N_ROWS_4]
    T_new = b[_B_T_NEW:_B_T_NEW + _N_T_4]
    T_new_by_4 = T_new.reshape((_N_T_4 // 4, 4))
    f, v_ramp = b[_B_F:_B_F + 3], k.v_ramp
    M_hold = holding_torque(grade, brake, k)  # what holds the vehicle at rest; the rest of M_resist needs motion
    g_sin_grade = k.g * math.sin(grade)  # the accelerometer's reading of the gradient
    sources = b[_B_SOURCES:_B_SOURCES + 4]
    decay_P, decay_slip = math.exp(-dt / k.tau), math.exp(-dt / k.tau_slip)  # of pressure_step, slip_memory_step
    decay_half = math.exp(-0.5 * dt / k.tau_slip)  # the slip memory half a step on
    mean_P = k.tau / dt * (1.0 - decay_P)  # the mean of exp(-t / tau) over the step: a pressure's mean
    target_CL, target_CH = clamp_command(P_CL_cmd, k), clamp_command(P_CH_cmd, k)
    # the pressure's parts of (6) (friction.pressure_factors) for the pressures they were last computed at
    P_CL_at = P_CH_at = math.nan
    factor_CL = log_CL = factor_CH = log_CH = 0.0
    b[_B_PERIOD] = b[S_TEMP + I_CL]
    b[_B_PERIOD + 1] = b[S_TEMP + I_CH]
    b[_B_PERIOD + 2] = 0.0
    b[_B_PERIOD + 3] = 0.0
    for step in range(n_steps):
        T_plate_CL, T_plate_CH = b[S_TEMP + I_CL], b[S_TEMP + I_CH]
        P_CL, P_CH = b[S_P], b[S_P + 1]
        P_CL_mean = target_CL + (P_CL - target_CL) * mean_P  # the exact means over the step [Pa]
        P_CH_mean = target_CH + (P_CH - target_CH) * mean_P
        v_start = vehicle_speed(b[S_X + _5], i_b, k.r_w)
        M_fixed, M_resist = road_load(v_start, grade, brake, k)
        fuel, d_integral = governor(b[S_X + _E], b[S_GOV], setpoint, k)
        M_e = net_torque(fuel, k)
        # clutch capacities (5)-(6) at the mean pressures, mu at the remembered slip (static mu once stuck long
        # enough)
        if P_CL_mean != P_CL_at:  # (a settled or open clutch's pressure stays the same, bit for bit)
            factor_CL, log_CL = pressure_factors(P_CL_mean, k)
            P_CL_at = P_CL_mean
        if P_CH_mean != P_CH_at:
            factor_CH, log_CH = pressure_factors(P_CH_mean, k)
            P_CH_at = P_CH_mean
        k_P_CL, k_P_CH = k.k_CL * P_CL_mean, k.k_CH * P_CH_mean  # torque per unit mu [N m]
        f[0], f[1], f[2] = b[S_F], b[S_F + 1], b[S_F + 2]
        mu_CL, mu_CH = contact_step(b, S_X, S_MEM, Mx_T, Mu_T, VG, W, v_ramp, M_e, M_fixed, M_hold, M_resist,
                                    k_P_CL, k_P_CH, T_plate_CL, T_plate_CH, factor_CL, log_CL, factor_CH, log_CH,
                                    decay_half, k)
        changed = modes_of(b)
        if changed or b[_B_STUCK] == 1.0 or b[_B_STUCK + 1] == 1.0:
            # a contact changed mode within the step, or a clutch is locked: the step again in sub-steps
            if changed:
                Q_CL, Q_CH, mu_CL, mu_CH = sub_steps(b, N_SUB, k.MxS_T, k.MuS_T, k.VGS, k.WS, M_e, M_fixed, M_hold,
                                                     M_resist, k_P_CL, k_P_CH, T_plate_CL, T_plate_CH, factor_CL,
                                                     log_CL, factor_CH, log_CH, k)
            else:
                Q_CL, Q_CH, mu_CL, mu_CH = sub_steps(b, N_LOCKED, k.MxL_T, k.MuL_T, k.VGL, k.WL, M_e, M_fixed,
                                                     M_hold, M_resist, k_P_CL, k_P_CH, T_plate_CL, T_plate_CH,
                                                     factor_CL, log_CL, factor_CH, log_CH, k)
        else:
            slip_CL, slip_CH = free[N_STATE], free[N_STATE + 1]  # mean slips [rad/s], exact over the step
            Q_CL = max(f[0] * slip_CL, 0.0)  # friction heat (4) [W]: the torque's work on the slip, exactly
            Q_CH = max(f[1] * slip_CH, 0.0)
            for i in range(N_STATE):
                b[S_X + i] = free[i]
            b[S_MEM] = slip_memory_relax(b[S_MEM], slip_CL, decay_slip)
            b[S_MEM + 1] = slip_memory_relax(b[S_MEM + 1], slip_CH, decay_slip)
        # thermal network: exact step with the sources of heat_sources(Q_CL, Q_CH, P_CL, P_CH)
        sources[0], sources[1], sources[2], sources[3] = Q_CL, Q_CH, P_CL, P_CH
        T_new[:] = 0.0
        add_products(T_new_by_4, PhiT_T, b, S_TEMP)
        for i in range(N_T):
            T_new[i] += T_const[i]
        add_products(T_new_by_4, T_srcT, sources, 0)
        for i in range(N_T):
            b[S_TEMP + i] = T_new[i]
        b[S_F], b[S_F + 1], b[S_F + 2] = f[0], f[1], f[2]
        b[S_GOV] += d_integral * dt
        b[S_P] = pressure_relax(P_CL, P_CL_cmd, decay_P, k)
        b[S_P + 1] = pressure_relax(P_CH, P_CH_cmd, decay_P, k)
        b[S_K] += 1.0
        b[S_T] = b[S_K] * dt_ns / 1e9  # the exact time in ns (an integer below 2**53), rounded once
        write_outputs(b, M_e, mu_CL, mu_CH, f[0], f[1], Q_CL, Q_CH, b[_B_STUCK], b[_B_STUCK + 1], b[_B_STUCK + 2],
                      Q_CL - k.C_CL * (T_new[I_CL] - T_plate_CL) / dt, Q_CH - k.C_CH * (T_new[I_CH] - T_plate_CH) / dt,
                      i_b, k.r_w, v_start, g_sin_grade, dt)
        b[_B_PERIOD] = max(b[_B_PERIOD], T_new[I_CL])
        b[_B_PERIOD + 1] = max(b[_B_PERIOD + 1], T_new[I_CH])
        b[_B_PERIOD + 2] += Q_CL * dt
        b[_B_PERIOD + 3] += Q_CH * dt
        if step < trace.shape[0]:
            for i in range(N_OUT):
                trace[step, i] = b[_B_OUT + i]
    return outputs_of(b)
