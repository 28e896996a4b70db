"""Contact laws side by side: why the 1-ms plant once missed the creep case's speeds, and the law it now has.

    python bench/contact_law.py [--seconds 3] [--long-seconds 30] [--json]

The plant (dsg_hil.physics.plant.advance_steps) holds every torque over a step and solves the three friction contacts
implicitly. It used to decide stick/slip on the contact velocities at the END of the step, with mu (6) at the slip
memory of the step's START and the capacities (5) at the pressures of the step's start (``OLD``); it now has the
law proposed here (``PLANT``). :class:`Stepper` is the same step in plain numpy (the plant's matrices and physics
functions; ``PLANT`` reproduces the compiled plant to rounding) with three choices:

* ``law="mean"``: stick/slip on the MEAN contact velocity over the step, v_mean = V (Phi_int x + Gamma_int u) / dt
  (linear in the torques as v_end is, the same projected Gauss-Seidel). A torque held over the step does work
  f dt v_mean, so a stuck contact does none and a slipping one dissipates |f| dt |v_mean|, at any step.
* ``law="mixed"`` (the plant's law): the clutches on the mean, the vehicle on its END speed
  (dsg_hil.physics.powertrain.law_rows). On the mean, a held vehicle's end speed flipped sign each step
  (v_end = -v_start: its speed is near-linear within a step), an undamped mode at the Nyquist frequency (braked
  from 0.2 m/s: +-0.34 mm/s, tau ~ 120 s); on its end speed a held vehicle ends every step at rest.
* ``mu_at="mid"``: mu at the slip memory half a step on (predicted from the step's mean slip, then the contacts
  solved again): the friction-slope feedback no longer lags half a step. ``mu_at="pred"``: the same memory
  predicted with the slips at the step's start (one solve; the plant's choice).
* The plant adds sub-steps (dsg_hil.physics.plant.N_SUB, N_LOCKED) where a contact changes mode and while a
  clutch is locked; :class:`Stepper` has none. ``side_by_side`` runs the compiled plant itself.
* ``P_mean=True``: the capacities (5) with each pressure's exact mean over the step instead of its value at the
  start (a pressure rising with tau no longer acts half a step late).

Measured (``modes``, linearised about the reference's state): while the vehicle is held and CL slips (t = 1.9 s),
the output gear train's 87.7-Hz mode (CL/CH outputs and shaft II against the held shaft III) has 0.286 % damping;
the old law at 1 ms gives it 0.047 % (the slope of mu, lagged a step, cancels damping), so it rings ~4x longer and
larger than it should (+-4.5 r/min against +-1.2). With the slip memory frozen, plant and continuous modes agree
exactly (the linear step is exact), and mu at mid-step restores 0.286 %. With CL locked (t = 2.5 s), the end-of-step
law moves the 6.2-Hz shuffle to 6.7 Hz and 161 Hz to 186 Hz; the mean law keeps 6.2 and 160 Hz. Both laws give the
held-phase mode the same damping: the stick law is not its cause.

``creep`` runs the bench's creep case (bench/plant_speed.py) against solve_hybrid at 1, 2, 5 and 10 ms for each
variant, errors as there (every 10 ms, speed error relative to full scale and in r/min); ``long`` runs the 30-s
stick/slip of all three contacts against the plant at 0.1 ms, finite and bounded at each step being the stability.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import time
from collections.abc import Callable

import numpy as np
from plant_speed import CREEP_BREAKPOINTS, PERIOD, creep_inputs, errors, run_plant

from dsg_hil.physics.continuous import rhs, solve_hybrid
from dsg_hil.physics.engine import governor, net_torque
from dsg_hil.physics.friction import friction_coefficient, slip_memory_step, torque_per_mu
from dsg_hil.physics.hydraulics import clamp_command, pressure_step
from dsg_hil.physics.params import Params, load_params
from dsg_hil.physics.powertrain import (CONTACT_INPUTS, IDX, N_DOF, N_STATE, holding_torque, road_load, solve_contacts,
                                        vehicle_speed)
from dsg_hil.physics.thermal import NODES, heat_sources
from dsg_hil.physics.plant import Plant, PlantInputs, PlantState

I_CL, I_CH = NODES.index("CL"), NODES.index("CH")
N_T = len(NODES)
# (law, mu_at, P_mean): the plant's old law, each change alone, and the plant's law (the last)
VARIANTS = (("end", "start", False), ("end", "mid", False), ("mean", "start", False), ("mean", "mid", False),
            ("mean", "mid", True), ("mean", "pred", True), ("mixed", "pred", True))
OLD, PLANT = VARIANTS[0], VARIANTS[-1]
STEPS = (1e-3, 2e-3, 5e-3, 1e-2)


class Stepper:
    """The plant's step with a choice of contact law and of where mu is evaluated (module docstring)."""

    def __init__(self, params: Params, dt: float, law: str = "end", mu_at: str = "start", P_mean: bool = False,
                 T_init: float = 80.0):
        self.plant = Plant(params, dt=dt, T_init=T_init)
        self.p, self.dt, self.law, self.mu_at, self.P_mean = params, dt, law, mu_at, P_mean
        # the mean over dt of P_cmd + (P - P_cmd) exp(-t / tau), as a weight of (P - P_cmd)
        self.mean_weight = params.hydraulics.tau / dt * (1.0 - math.exp(-dt / params.hydraulics.tau))
        d = self.plant.disc
        self.Phi, self.Gamma = d.Phi, d.Gamma
        end, mean = (d.V @ d.Phi, d.V @ d.Gamma), (d.V @ d.Phi_int / dt, d.V @ d.Gamma_int / dt)
        self.V_mean = mean
        # contact velocities the law acts on: x, u -> v
        self.V_law = end if law == "end" else mean if law == "mean" else (d.L_x, d.L_u)
        self.W = self.V_law[1][:, list(CONTACT_INPUTS)]
        s = self.plant.state
        self.x, self.T, self.P = s.x, s.T, np.array([s.P_CL, s.P_CH])
        self.governor_integral, self.f, self.memory = s.governor_integral, s.contact_torques, s.slip_memory
        self.stuck = np.zeros(3, dtype=bool)
        self.v_ramp = np.array([1.0, 1.0, params.vehicle.v_stick / params.vehicle.r_w * params.powertrain.i_b])

    def capacities(self, memory: np.ndarray, P: np.ndarray, M_hold: float) -> np.ndarray:
        p = self.p
        k = (torque_per_mu(p.clutch.CL, 1.0), torque_per_mu(p.clutch.CH, 1.0))  # N m per Pa (5)
        mu_CL = friction_coefficient(memory[0], self.T[I_CL], P[0], p.friction)
        mu_CH = friction_coefficient(memory[1], self.T[I_CH], P[1], p.friction)
        return np.array([mu_CL * k[0] * P[0], mu_CH * k[1] * P[1], M_hold])

    def step(self, inputs: PlantInputs) -> None:
        p, dt, x = self.p, self.dt, self.x
        grade = p.vehicle.beta if inputs.grade is None else inputs.grade
        setpoint = p.engine.omega_idle if inputs.engine_speed_request is None else inputs.engine_speed_request
        M_fixed, M_resist = road_load(vehicle_speed(x[IDX["5"]], p.powertrain.i_b, p.vehicle.r_w), grade,
                                      inputs.brake, p.vehicle)
        fuel, d_integral = governor(x[IDX["e"]], self.governor_integral, setpoint, p.engine)
        M_e = net_torque(fuel, p.engine)
        of_x, of_u = self.V_law
        v_free = of_x @ x + of_u @ np.array([M_e, 0.0, 0.0, M_fixed])
        P = self.P
        if self.P_mean:
            target = np.array([clamp_command(inputs.P_CL_cmd, p.hydraulics),
                               clamp_command(inputs.P_CH_cmd, p.hydraulics)])
            P = target + (self.P - target) * self.mean_weight
        M_hold = holding_torque(grade, inputs.brake, p.vehicle)
        memory = self.memory
        if self.mu_at == "pred":  # the memory half a step on, predicted with the present slips
            slips = self.x[IDX["1"]] - self.x[[IDX["2"], IDX["3"]]]
            memory = np.array([slip_memory_step(self.memory[i], slips[i], dt / 2, p.friction) for i in range(2)])
        cap = self.capacities(memory, P, M_hold)
        f = solve_contacts(v_free, self.W, cap, limits(cap, M_resist), self.v_ramp, self.f)
        slip_mean = self.mean_velocities(M_e, f, M_fixed)
        if self.mu_at == "mid":
            memory = np.array([slip_memory_step(self.memory[i], slip_mean[i], dt / 2, p.friction) for i in range(2)])
            cap = self.capacities(memory, P, M_hold)
            f = solve_contacts(v_free, self.W, cap, limits(cap, M_resist), self.v_ramp, f)
            slip_mean = self.mean_velocities(M_e, f, M_fixed)
        Q = np.maximum(f[:2] * slip_mean[:2], 0.0)  # friction heat (4), W
        self.x = self.Phi @ x + self.Gamma @ np.array([M_e, f[0], f[1], M_fixed + f[2]])
        self.T = self.plant.thermal.step(self.T, heat_sources(p, Q[0], Q[1], self.P[0], self.P[1]))
        self.stuck, self.f = np.abs(f) < cap * (1.0 - 1e-9), f
        self.memory = np.array([slip_memory_step(self.memory[i], slip_mean[i], dt, p.friction) for i in range(2)])
        self.governor_integral += d_integral * dt
        self.P = np.array([pressure_step(self.P[0], inputs.P_CL_cmd, dt, p.hydraulics),
                           pressure_step(self.P[1], inputs.P_CH_cmd, dt, p.hydraulics)])

    def mean_velocities(self, M_e: float, f: np.ndarray, M_fixed: float) -> np.ndarray:
        of_x, of_u = self.V_mean
        return of_x @ self.x + of_u @ np.array([M_e, f[0], f[1], M_fixed + f[2]])

    def run(self, inputs_at: Callable[[float], PlantInputs], seconds: float) -> tuple[np.ndarray, np.ndarray]:
        """(speeds, [T_CL, T_CH]) every control period; FloatingPointError if the state stops being finite."""
        n = int(round(PERIOD / self.dt))
        speeds, temps = [], []
        for k in range(int(round(seconds / PERIOD))):
            inputs = inputs_at(k * PERIOD)
            for _ in range(n):
                self.step(inputs)
            if not (np.all(np.isfinite(self.x)) and np.abs(self.x[:N_DOF]).max() < 1e4):
                raise FloatingPointError(f"diverged by t = {(k + 1) * PERIOD:.2f} s")
            speeds.append(self.x[:N_DOF])
            temps.append((self.T[I_CL], self.T[I_CH]))
        return np.array(speeds), np.array(temps)


def limits(cap: np.ndarray, M_resist: float) -> np.ndarray:
    """The contacts' torques when slipping fast: the clutches' capacities, the vehicle's full road resistance."""
    return np.array([cap[0], cap[1], M_resist])


def linearised_modes(params: Params, y0: np.ndarray, inputs: PlantInputs, stuck: tuple[bool, bool, bool],
                     dts: tuple[float, ...]) -> dict:
    """Modes (Hz, damping ratio %) above 2 Hz of z = [x, CL slip memory] linearised at y0 (a state of
    dsg_hil.physics.continuous; T, P and the governor frozen): continuous with the contacts in ``stuck``
    (as solve_hybrid), and the step map of each variant at each dt (which must keep the same contacts stuck)."""
    i_mem = N_STATE + N_T + 3
    idx = [*range(N_STATE), i_mem]

    def jacobian(F: Callable[[np.ndarray], np.ndarray], h: float) -> np.ndarray:
        z0 = y0[idx]
        J = np.empty((len(z0), len(z0)))
        for j in range(len(z0)):
            dz = np.zeros(len(z0))
            dz[j] = h * max(1.0, abs(z0[j]))
            J[:, j] = (F(z0 + dz) - F(z0 - dz)) / (2 * dz[j])
        return J

    def modes(s: np.ndarray) -> list[tuple[float, float]]:
        hz, zeta = s.imag / (2 * np.pi), -s.real / np.maximum(np.abs(s), 1e-300)
        return sorted((round(float(a), 1), round(float(b) * 100, 3)) for a, b in zip(hz, zeta) if a > 2.0)

    f = rhs(Plant(params, T_init=80.0), inputs, stuck=stuck, direction=(1.0, 1.0, 1.0))

    def continuous(z: np.ndarray) -> np.ndarray:
        y = y0.copy()
        y[idx] = z
        return f(0.0, y)[idx]

    out: dict[str, list | str] = {"continuous": modes(np.linalg.eigvals(jacobian(continuous, 1e-6)))}
    for dt in dts:
        for variant in VARIANTS:
            stepper = Stepper(params, dt, *variant)
            step_map = functools.partial(map_of_step, stepper, y0, inputs, stuck)
            try:
                lam = np.linalg.eigvals(jacobian(step_map, 1e-7)).astype(complex)
            except ModeChangeError as e:  # this step does not even keep the contacts' modes: nothing to linearise
                out[label(variant, dt)] = str(e)
                continue
            lam = lam[np.abs(lam) > 1e-12]
            out[label(variant, dt)] = modes(np.log(lam) / dt)
    return out


class ModeChangeError(Exception):
    """A step from the linearisation point changes which contacts are stuck."""


def map_of_step(stepper: Stepper, y0: np.ndarray, inputs: PlantInputs, stuck: tuple[bool, bool, bool],
                z: np.ndarray) -> np.ndarray:
    """One step of ``stepper`` from z = [x, CL slip memory], the rest of the state from y0 (linearised_modes)."""
    i_mem = N_STATE + N_T + 3
    stepper.x, stepper.memory = z[:N_STATE].copy(), np.array([z[-1], y0[i_mem + 1]])
    stepper.T, stepper.P = y0[N_STATE:N_STATE + N_T].copy(), y0[N_STATE + N_T:N_STATE + N_T + 2].copy()
    stepper.governor_integral, stepper.f = y0[N_STATE + N_T + 2], np.array([100.0, 0.0, 100.0])
    stepper.step(inputs)
    if tuple(stepper.stuck) != stuck:
        raise ModeChangeError(f"one step sticks {[c for c, k in zip(('CL', 'CH', 'vehicle'), stepper.stuck) if k]}")
    return np.concatenate([stepper.x, [stepper.memory[0]]])


def side_by_side(held: dict, locked: dict, dt: float = 1e-3) -> dict:
    """The modes side by side, continuous vs the old law vs the plant at ``dt``: the 88-Hz mode
    of the held vehicle (Hz, damping %, 1/e decay time 1/(zeta omega) [s], the amplitude left after 12 s) and the
    shuffle with CL locked (Hz, damping %), from :func:`linearised_modes`."""
    def nearest(modes: list | str, hz: float) -> tuple[float, float]:
        return (math.nan, math.nan) if isinstance(modes, str) else min(modes, key=lambda m: abs(m[0] - hz))

    rows = {}
    for name, key in (("continuous", "continuous"), ("old law", label(OLD, dt)), ("plant law", label(PLANT, dt))):
        (hz, zeta), shuffle = nearest(held[key], 87.7), nearest(locked[key], 6.2)
        rate = zeta / 100.0 * 2.0 * math.pi * hz  # 1/s, zeta omega (light damping: omega_d ~ omega_n)
        rows[name] = {"mode_88_hz": hz, "mode_88_damping_pct": zeta, "mode_88_decay_s": 1.0 / rate,
                      "mode_88_left_after_12_s": math.exp(-12.0 * rate), "shuffle_hz": shuffle[0],
                      "shuffle_damping_pct": shuffle[1]}
    return rows


def common_state(params: Params, t: float, dt: float = 5e-5) -> np.ndarray:
    """The plant's state array at ``t`` on the creep case, stepped at ``dt`` (fine: close to the continuous model)."""
    plant = Plant(params, dt=dt, T_init=80.0)
    n = int(round(PERIOD / dt))
    for k in range(int(round(t / PERIOD))):
        plant.advance(creep_inputs(k * PERIOD), n)
    return plant.state.array.copy()


def run_from(params: Params, state: np.ndarray, dt: float, inputs: PlantInputs, seconds: float,
             law: tuple[str, str, bool] | None = None) -> np.ndarray:
    """Every 1 ms for ``seconds`` from ``state``: [omega_CL, omega_out] of the compiled plant at ``dt`` (law None)
    or of :class:`Stepper` with ``law``."""
    n = int(round(1e-3 / dt))
    rows = []
    if law is None:
        plant = Plant(params, dt=dt, T_init=80.0)
        plant._s[:] = state  # the bench's one reach into the plant: the same state for every run
        for _ in range(int(round(seconds / 1e-3))):
            out = plant.advance(inputs, n)
            rows.append((out.omega_CL, out.omega_out))
        return np.array(rows)
    stepper = Stepper(params, dt, *law)
    st = PlantState(state)
    stepper.x, stepper.T, stepper.P = st.x, st.T, np.array([st.P_CL, st.P_CH])
    stepper.governor_integral, stepper.f, stepper.memory = st.governor_integral, st.contact_torques, st.slip_memory
    for _ in range(int(round(seconds / 1e-3))):
        for _ in range(n):
            stepper.step(inputs)
        rows.append((stepper.x[IDX["2"]], stepper.x[IDX["5"]]))
    return np.array(rows)


PP_AT = (0.1, 1.0, 3.0, 12.0)  # s, the ends of the windows of time_side_by_side's peak-to-peak


def time_side_by_side(params: Params) -> dict:
    """The 88-Hz mode's decay and the shuffle frequency in time, from common states (the plant at 0.05 ms, as the
    continuous model): the held vehicle with CL slipping (creep case at 1.9 s, 12 s on) and CL locked with the vehicle
    rolling (at 2.5 s, 2 s on); the plant at 0.05 ms (reference), the plant at 1 ms and the old law at 1 ms. The
    88-Hz figure is the CL output speed's peak-to-peak over the 0.1 s before 0.1, 1, 3 and 12 s [rad/s] (as the
    plate heats, mu's slope undamps the mode and the converged model judders), the shuffle the peak of the output
    shaft speed's spectrum (linear trend removed) between 2 and 20 Hz [Hz]."""
    held, locked = common_state(params, 1.9), common_state(params, 2.5)
    runs = {"plant 0.05 ms": (5e-5, None), "plant 1 ms": (1e-3, None), "old law 1 ms": (1e-3, OLD)}
    out = {}
    for name, (dt, law) in runs.items():
        ring = run_from(params, held, dt, PlantInputs(P_CL_cmd=0.5e6, brake=1.0), 12.0, law)[:, 0]
        shuffle = run_from(params, locked, dt, PlantInputs(P_CL_cmd=1.0e6), 2.0, law)[:, 1]
        t = np.arange(len(shuffle)) * 1e-3
        rest = shuffle - np.polyval(np.polyfit(t, shuffle, 1), t)
        spectrum = np.abs(np.fft.rfft(rest, 16 * len(rest)))
        hz = np.fft.rfftfreq(16 * len(rest), 1e-3)
        band = (hz > 2.0) & (hz < 20.0)
        pp = {f"{end:g} s": float(np.ptp(ring[int(round(end * 1e3)) - 100:int(round(end * 1e3))])) for end in PP_AT}
        out[name] = {"mode_88_pp": pp,
                     "shuffle_hz": float(hz[band][np.argmax(spectrum[band])])}
    return out


def creep(params: Params, seconds: float) -> tuple[dict, np.ndarray]:
    """Each variant at each step against solve_hybrid on the bench's creep case; also the reference's samples."""
    t_eval = np.arange(1, int(round(seconds / PERIOD)) + 1) * PERIOD
    breakpoints = [b for b in CREEP_BREAKPOINTS if b < seconds] + [seconds]
    ref, _ = solve_hybrid(Plant(params, T_init=80.0), creep_inputs, breakpoints, t_eval, rtol=1e-8)
    ref_speeds, ref_T = ref[:, :N_DOF], ref[:, [N_STATE + I_CL, N_STATE + I_CH]]
    return compare(params, seconds, ref_speeds, ref_T), ref


def label(variant: tuple[str, str, bool], dt: float) -> str:
    law, mu_at, P_mean = variant
    return f"{law}/{mu_at}{'/P_mean' if P_mean else ''} {dt * 1e3:g} ms"


def compare(params: Params, seconds: float, ref_speeds: np.ndarray, ref_T: np.ndarray,
            variants: tuple[tuple[str, str, bool], ...] = VARIANTS) -> dict:
    """Each variant at each step on creep_inputs: its errors against the reference samples (every period)."""
    out: dict[str, dict] = {}
    for dt in STEPS:
        for variant in variants:
            name = label(variant, dt)
            t0 = time.process_time()
            try:
                speeds, temps = Stepper(params, dt, *variant).run(creep_inputs, seconds)
            except FloatingPointError as e:
                out[name] = {"diverged": str(e)}
                continue
            T_err, fs, rpm = errors(speeds, temps, ref_speeds, ref_T)
            v_err = np.abs(speeds[:, IDX["5"]] - ref_speeds[:, IDX["5"]]).max() / params.powertrain.i_b
            out[name] = {"max_plate_error_c": T_err, "max_speed_error_fs": fs, "max_speed_error_rpm": rpm,
                         "max_vehicle_speed_error_mm_s": v_err * params.vehicle.r_w * 1e3,
                         "python_cpu_s": time.process_time() - t0}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=3.0, help="creep case against solve_hybrid (default 3)")
    ap.add_argument("--long-seconds", type=float, default=30.0,
                    help="all-contact stick/slip against the plant at 0.1 ms (default 30; 0: skip)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    params = load_params()
    result: dict = {}
    result["creep"], ref = creep(params, args.seconds)
    held, locked = ref[int(round(1.9 / PERIOD)) - 1], ref[int(round(2.5 / PERIOD)) - 1]
    result["modes_vehicle_held_CL_slipping"] = linearised_modes(
        params, held, PlantInputs(P_CL_cmd=0.5e6, brake=1.0), (False, False, True), STEPS)
    result["modes_CL_locked_vehicle_rolling"] = linearised_modes(
        params, locked, PlantInputs(P_CL_cmd=1.0e6), (True, False, False), STEPS)
    result["time_side_by_side"] = time_side_by_side(params)
    result["side_by_side_1ms"] = side_by_side(result["modes_vehicle_held_CL_slipping"],
                                              result["modes_CL_locked_vehicle_rolling"])
    if args.long_seconds > 0:
        ref_speeds, ref_T, _, _ = run_plant(Plant(params, dt=1e-4, T_init=80.0), creep_inputs, args.long_seconds,
                                            PERIOD)
        result["long"] = compare(params, args.long_seconds, ref_speeds, ref_T, (OLD, PLANT))
    if args.json:
        print(json.dumps(result))
        return
    for case in ("creep", "long"):
        if case not in result:
            continue
        print(f"{case}: {'variant':<20}{'dT plate K':>11}{'speed/FS':>10}{'r/min':>9}{'vehicle mm/s':>14}")
        for name, r in result[case].items():
            if "diverged" in r:
                print(f"  {name:<30}{r['diverged']}")
                continue
            print(f"  {name:<30}{r['max_plate_error_c']:>11.4f}{r['max_speed_error_fs']:>10.4f}"
                  f"{r['max_speed_error_rpm']:>9.2f}{r['max_vehicle_speed_error_mm_s']:>14.1f}")
    print("in time, from common states (time_side_by_side): 88-Hz ringing of the CL output, peak-to-peak over the "
          f"0.1 s before {', '.join(f'{t:g}' for t in PP_AT)} s [rad/s]; shuffle with CL locked [Hz]")
    for name, r in result["time_side_by_side"].items():
        print(f"  {name:<14}" + "".join(f"{v:11.4g}" for v in r["mode_88_pp"].values())
              + f"   shuffle {r['shuffle_hz']:6.2f} Hz")
    print("linearised (Stepper, no sub-steps) at 1 ms: 88-Hz mode of the held vehicle (Hz, damping %, 1/e decay s, "
          "left after 12 s); shuffle with CL locked (Hz, damping %)")
    for name, r in result["side_by_side_1ms"].items():
        print(f"  {name:<12}{r['mode_88_hz']:7.1f} Hz {r['mode_88_damping_pct']:7.3f} % {r['mode_88_decay_s']:7.2f} s"
              f" {r['mode_88_left_after_12_s']:9.2e}   shuffle {r['shuffle_hz']:5.2f} Hz "
              f"{r['shuffle_damping_pct']:7.3f} %")
    for key in ("modes_vehicle_held_CL_slipping", "modes_CL_locked_vehicle_rolling"):
        print(f"{key} (Hz, damping %):")
        for name, modes in result[key].items():
            print(f"  {name:<30}" + (modes if isinstance(modes, str) else
                                     "  ".join(f"{hz:7.1f} {z:+7.3f}" for hz, z in modes if hz < 200.0)))


if __name__ == "__main__":
    main()
