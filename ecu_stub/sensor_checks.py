"""Plausibility of the TCU's thermal inputs: the measured pressures, the clutch input speed and the oil leaving each
clutch, each checked against redundant information the TCU has.

The plate prediction (:mod:`ecu_stub.clutch_model`) and the thermal monitor use ``P_CL/P_CH`` (the heat is
mu k_geom P |slip|), ``ClutchInputSpeed`` (the slip) and ``T_OilCL/T_OilCH`` (the plate cools towards them). A
frame with a valid CRC and counter can carry a wrong value: on a 20-s creep from CL 228 degC / CH 245 degC / oil
130 degC on Table I's grade, without these checks, ``T_OilCL`` stuck at 40 degC took CL's true plate to
300 degC, ``P_CL`` stuck at 0 to 253 degC. Each check below is debounced as the speed vote
(:mod:`ecu_stub.plausibility`): a one-sided CUSUM of the excess beyond a tolerance, failing once it passes a bound
that a sensor without a fault cannot reach, and for :data:`~ecu_stub.plausibility.HEAL_S` after (a cycle counts at
most :data:`~ecu_stub.plausibility.MAX_DT_S`, the matrix's :attr:`MatrixSteps.max_dt_s`). A run without a sensor
fault never reaches a bound, so the TCU gets the very same inputs, and sends the very same frames, as without the
checks.

**1. Measured pressure vs the TCU's own command** (:class:`PressureCheck`). The piston pressure follows the command
with a first-order lag ``strategy.hydraulic_lag_s`` = 50 ms (identified, ``calibration.toml``; the plant's
``hydraulics.tau``). The TCU models it: P_m <- cmd + (P_m - cmd) exp(-dt / lag), with cmd the command it sent the
cycle before (the plant applies it over the next period and measures at the next tick).

* Tolerance ``tol = q_P + q_cmd + P_ABS_MPA + P_REL * max(P, P_m)``: half a DBC step of each (0.05 kPa), 0.02 MPa
  (1 % of the DBC's 2-MPa range, a pressure sensor's accuracy) and 5 % of the pressure (the valve's gain).
* Bound on the integral of the excess, ``P_IMPULSE_MPA_S`` = 0.075 MPa s: two first-order lags tau_a, tau_b of the
  same command step dP differ by dP (exp(-t/tau_a) - exp(-t/tau_b)), whose integral is dP (tau_a - tau_b): with
  the lag known within 20 ms (40 % of 50 ms: a solenoid's lag changes with the oil's viscosity) and dP at most the
  command range 1.5 MPa, 0.03 MPa s; x2 for a swing from one sign to the other: 0.06 MPa s. Plus in real time a
  command reaching the valve one 10-ms cycle late: 10 ms x 1.5 MPa = 0.015 MPa s (0 in lock-step).
  A P_CL stuck at 0 under a creep pressure of 0.3 MPa passes it in about 0.3 s.
* Reaction: the larger of the measured and the modelled pressure (the heat is monotonic in P: the prediction stays
  on the safe side whichever of the two is wrong; a valve that really does not follow its command is as
  implausible, and then the measurement is the larger). A launch's brake is not released on an implausible
  pressure (``TcuInputs.pressure_trusted``): with a valve that builds no pressure the modelled pressure would say
  the pre-fill carries the vehicle (4.5 m of roll-back on Table I's grade), so the vehicle stays held. Frames of
  the TCU's lost on the bus trip this check too (the plant's fallback releases the pressures while the model
  follows the commands; 0.082 MPa s for 0.5 s of dropped TCU_CMD): the larger, the command, is then used.

**2. Clutch input speed vs engine speed** (:class:`InputSpeedCheck`). Shaft I (both clutch drums) turns with the
engine through the reduction ``vehicle.input_ratio`` (i_a = 5.3585, Table I; in the calibration with its source)
and two shafts (K_in, K_a1): omega_I = omega_e / i_a plus what the shafts twist.

* Tolerance ``tol = q_in + q_e / i_a + N_ABS_RPM + N_REL * max``: half a DBC step of each (0.05 r/min;
  0.125 r/min / i_a), 1 % (the published ratio's rounding) and ``N_ABS_RPM`` = 40 r/min for a ringing shaft: a
  cold pack's high friction excites the clutch-hub modes (~330 Hz, Table I's damping 0.5 N m s/rad), and sampled
  every 10 ms these alias to a slow apparent difference of their amplitude, which no integral bounds: 23.3 r/min
  measured (plates at 40 degC, oil 150 degC, Table I's grade), 1 r/min in the other closed-loop runs; x1.7. (The
  angle bound then holds only for the true twist, which the tolerance does not need.)
* Bound on the angle between the two (the integral of the speed difference), ``ANGLE_RAD`` = 0.5 rad at shaft I:
  the clutches' largest torque, 2 x mu k_geom P_max = 2 x 0.07 x 0.027338 m^3 x 1.5 MPa = 5.74 kN m, twists K_a1 =
  89389 N m/rad by 0.064 rad (and K_in = 283429 N m/rad, at the engine, by 0.004 rad / i_a); x2 for a step's
  overshoot and x2 for a swing: 0.26 rad. Plus in real time PLANT_ENGINE and PLANT_SPEEDS held from frames one
  10-ms cycle apart: 10 ms x 20 rad/s of shaft-I speed change (an idle step of 1000 r/min at the engine): 0.2 rad.
  An input speed stuck at 0 at the 800-r/min idle (149 r/min at shaft I) passes it in about 0.05 s; one that reads
  less than 40 r/min under the truth is not caught here; the thermal model takes the larger of the two in every
  cycle (:meth:`ecu_stub.controller.CreepController.input_rpm`), so it does not under-predict the heat by it.
* Reaction: the larger of the two speeds (the larger slip: a clutch's input turns faster than its output while it
  drives the vehicle, so the heat predicted is the larger; an engine speed stuck high only makes the TCU stop
  early).

**3. Oil leaving a clutch vs its balance with the plate and the sump** (:class:`OilCheck`). The oil leaving a
pack has been fed from the sump (through pump and valve) and has passed the plates; it settles within 0.18 s
(``strategy.startup_observer_s``' derivation) to the balance K (T_plate - T_out) = cooling (T_out - T_sump) that the
start-up observer uses, with the identified ``K_plate_oil_w_k`` and ``cooling_w_k``:

    T_balance = (K T_plate + cooling T_sump) / (K + cooling)          (CL: 99.6 % plate; CH: 92.4 %)

with the TCU's plate estimate of the last cycle for T_plate. A plate colder than the sump (a cold pack in hot oil)
legitimately cools its oil below the sump's: the balance follows it, a comparison with the sump alone would not.
The check is one-sided: oil reading *colder* than the balance makes the prediction cool its plate too fast (the
hazard); hotter is on the safe side.

* Tolerance ``OIL_TOL_K`` = 10 K: 3.5 K the prediction's error (``strategy.prediction_error_k``, taken as large
  over the truth as under it), 1 K the fit of the balance (RMS 0.90 K CL, 0.55 K CH, ``calibration.toml``), 1 K
  the oil's lag behind a plate heating at 5 K/s (0.18 s), 0.5 K of PLANT_OIL_TEMP's 100-ms cycle at that rate, 1 K
  the losses of pump, valve and pack to the environment (the feed is not quite the sump), 0.1 K the DBC steps:
  7.1 K, rounded up to 10 K for conditions beyond the identification runs. (The calibration's prediction error is
  2 K since its re-identification of 2026-12-03 (ddbc62e): 5.6 K; the tolerance is kept, the later catch of the
  two.)
* Bound on the integral of the excess, ``OIL_KS`` = 2 K s (a deficit 10 K beyond the tolerance for 0.2 s). Its
  cost: until it is passed the prediction cools towards the wrong value, (K / C) x the integral of the oil's error:
  a T_OilCL stuck at 40 degC under a 228-degC plate passes it in 2 cycles (deficit 178 K beyond the tolerance), in
  which CL's prediction may lose up to K / C x 188 K x 0.02 s = 0.667 /s x 3.8 K s = 2.5 K (the adiabatic
  substitute then makes up for more: measured, CL's truth peaks at 240.8 degC against 245.4 degC without the
  fault). The largest integral without a sensor fault, 0.34 K s (a cold pack in hot oil: plates 40 degC, oil
  150 degC), leaves a factor 6.
* Reaction: the prediction takes as that clutch's oil the hottest credible value: the measurement, the sump and
  the plate estimate itself, the largest (with the plate's own estimate the plate exchanges no heat: an adiabatic,
  conservative prediction).

**4. The oil's fall vs the plate's fastest passive cooling** (:class:`OilCheck`, ``cooling_per_s``). Check 3
compares the reading with a balance built from the TCU's own plate estimate, which follows the reading (CL's
plate-oil time constant 1.5 s): an offset from an onset passed it up to 16 K on CL, 12 K on CH (docs/safety.md).
But the oil leaving a pack sits at its balance with the plate (CL: 99.6 % plate), and without friction
heat a plate cools at most at K_eff (T - T_sump) / C, K_eff = K cooling / (K + cooling) (the balance eliminated:
CL 3.4 W/K over 1,378 J/K, 0.37 K/s at 150 K over the sump; CH 69 W/K over 6,908 J/K, 1.5 K/s); with heat, slower.
So a reading that falls faster has stepped: a one-sided CUSUM of the reading's fall beyond ``FALL_GAIN`` x that
rate (at the plate estimate), failing once it passes ``OIL_FALL_K``.

* ``FALL_GAIN`` = 2: what the calibration's K_eff / C leaves out (losses of plates and pack to the housing, the
  oil's own capacity; CL cooled 1.3 times as fast as K_eff / C says in the default scenario, 205-243 degC):
  with 1 the largest fall's CUSUM without a sensor fault was 4.8 K (the default scenario), with 2, 0.18 K over it and
  the 89 identification runs.
* ``OIL_FALL_K`` = 0.5 K: two DBC steps (0.2 K; the largest value without a sensor fault, 0.18 K, is one step
  rounded each way) and 0.3 K for a real sensor's noise (assumed).
* It starts ``FALL_START_TAU`` = 8 oil time constants (1.6 s) after the first cycle: a cold pack in hot oil settles
  from the sump's temperature to its plate's within the start-up observer's five (e^-5 of 110 K is 0.7 K, of the
  eighth 0.04 K). Before, the settling check (6) judges the reading.
* Reaction: the reading is not trusted again until the TCU restarts (a latched fault: a step does not come back,
  so healing on agreement would trust the offset reading 2 s later); the hottest credible value as in 3 (the
  plate's own estimate: no cooling assumed).

What it does not see: a step within ``OIL_FALL_K`` plus the plate's rise over one PLANT_OIL_TEMP frame (100 ms; a
step during a fast heating hides in it), a drift slower than ``FALL_GAIN`` x the passive cooling, and an offset
present when it starts (check 5). The strategy's margin budgets the first, as an offset and as a gain grown from
the lowest reading to T_safe, and the last (:meth:`ecu_stub.controller.CreepController.oil_margin_k`); the drift
stays assumed away (docs/safety.md).

**5. The oil temperatures at key-on vs each other** (:meth:`SensorChecks.check`, ``keyon``). Once the TCU runs, an
oil sensor's offset is unobservable: the oil leaving a pack sits at its plate's balance, and nothing else the TCU
measures depends on the plate. At key-on it is not: the circuit's oil has stood mixed (the plant starts every oil
node at the scenario's ``T_oil_c``: the packs' oil, the sump's, the radiator's), and the packs' oil leaves that
temperature for its plate's only with the pack's oil time constant (0.17-0.18 s,
``strategy.startup_observer_s``' derivation). So the key-on frame's ``T_OilCL``, ``T_OilCH`` and ``T_Sump`` read one
temperature, each within its sensor's accuracy: the rule compares them on the TCU's first cycle, if that comes
before a second PLANT_OIL_TEMP frame can have (``now`` < :data:`OIL_FRAME_S`, the matrix's
:attr:`MatrixSteps.oil_frame_s`: in lock-step the plant's time).

* Tolerance :func:`keyon_tolerance_k` = 2 a(T) + 2 q: two healthy sensors of accuracy a(T) = :data:`CLASS_ABS_K`
  + :data:`CLASS_REL` |T| (IEC 60751 class B, the calibration's ``strategy.oil_accuracy_k`` is its value at T_safe)
  read one temperature at most that far apart, q = :data:`OIL_Q_K` half the DBC's step each; T the highest reading
  (the larger tolerance). 1.7 K at 100 degC.
* Rule: a pack's reading more than that below the **highest** of the three is not trusted for the rest of the
  operation cycle (one-sided, the hazard's side: a reading too high only costs availability). The highest, not a
  vote: two pack sensors low by about the same (two faults) would out-vote a right sump.
* Undetected: with at least one of the other two sensors healthy (not reading more than a(T) low), a pack's reading
  passes only if it is at most :func:`keyon_undetected_k` = tolerance + a(T) + q below the truth (2.55 K at
  100 degC); an offset keeps that error as the plate heats, and the margin budgets it (``margin_k``). A gain g
  (reading g T in degC) passes with (1 - g) T0 within it and its error then grows with T / T0: the margin budgets
  it grown to T_safe, from the coldest the key-on oil may have been (``oil_margin_k``).
* Reaction: as the fall check's (latched), but the plate estimate that the substitute keeps is started from the
  hottest a plate may start (:data:`START_PLATE_MAX_C`, the operating range's) or the readings, the larger: the
  flagged clutch's plate is unobservable, so it is predicted adiabatic from the hottest credible start. Until the
  fall check's start (after the start-up observer) the substitute is that start (or a hotter reading) alone: the
  observer, which adds cooling / K of the oil's excess over the sump, would otherwise grow on its own estimate.

**6. The oil settling after key-on** (:class:`SettleCheck`, until the fall check starts). The oil leaving a pack
leaves the key-on temperature for its balance with the plate as an exponential of the pack's oil time constant
C_oil / (K + cooling) (0.17-0.18 s by ``strategy.startup_observer_s``' derivation; the plant's readings shrink by
0.553-0.558 per 100-ms frame, 0.17 s). Its changes from frame to frame form a geometric row, whatever the plate's
temperature, which the TCU does not know yet. So, in whole oil frames (a frame's jitter in real time ignored; a
frame without a change is a change of 0 K):

* each change against the one before, carried by :func:`settle_factor` at a time constant between
  :data:`SETTLE_TAU_LO` (0.75) x and 1 x the calibration's ``startup_observer_s`` / 5 (0.15-0.2 s): lower than
  that is a step now; higher, while no friction heat can come (the start-up observer's window: the TCU does not
  creep), is a step in the change before (a fall that stops dead, a rise that grows);
* while no heat can come, three changes in a row of one sign against c2^2 = c1 c3, in kelvin of the middle change
  (its step that explains the difference): this needs no time constant, so a step in the middle one is seen to
  within its quantisation, and one in the first (the key-on frame's change, which has no change before it) to
  within 2 / R of that.
* Tolerance: two half DBC steps per change (0.1 K) plus the plate's passive cooling over it (x ``FALL_GAIN``), on
  each change the comparison takes; the excess adds up in a CUSUM that fails past ``OIL_FALL_K`` (latched, as 4).
* What passes, per change: the time constant's spread on the change before plus the slack and the bound, or, once
  a geometric row checked it, the row's tolerance and the bound (x 2 / R for the first change). Per degC of the
  reading (at least :data:`GAIN_FLOOR_C`), its largest value is :attr:`SettleCheck.ratio`: a gain beginning
  while the oil settled, which the margin grows to T_safe (``CreepController.oil_margin_k``). On the plant, without a
  sensor fault, the CUSUM stayed under 0.18 K over 60 starts from plates of 30-250 degC in oil of 30-160 degC.

Not covered: a value stuck at what the redundant information says (a sensor frozen at its last value while nothing
changes); for the oil, all three sensors low together at key-on (a common-mode fault), and a TCU whose first frames
are not key-on's (a lost first PLANT_OIL_TEMP frame, a TCU started after the gearbox): the key-on check is then not
made. There is no FAULT reaction here: each check has a conservative substitute that needs no other sensor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from .plausibility import MAX_DT_S, Sustained

__all__ = ["ANGLE_RAD", "CHECKED", "CLASS_ABS_K", "CLASS_REL", "FALL_GAIN", "FALL_START_TAU", "GAIN_FLOOR_C",
           "InputSpeedCheck", "MatrixSteps", "N_ABS_RPM", "N_REL", "OIL_FALL_K", "OIL_FRAME_S", "OIL_KS", "OIL_Q_K",
           "OIL_TOL_K", "OilCheck", "P_ABS_MPA", "P_IMPULSE_MPA_S", "P_REL", "PressureCheck", "SETTLE_TAU_LO",
           "START_PLATE_MAX_C", "SensorChecks", "SettleCheck", "keyon_tolerance_k", "keyon_undetected_k",
           "oil_accuracy_at", "settle_factor"]

P_ABS_MPA = 0.02  # pressure sensor accuracy: 1 % of the DBC's 2-MPa range [MPa]
P_REL = 0.05  # the valve's gain [1]
P_IMPULSE_MPA_S = 0.075  # lag uncertainty 2 x 20 ms x 1.5 MPa + real-time skew 10 ms x 1.5 MPa [MPa s]
N_REL = 0.01  # input reduction i_a as published [1]
N_ABS_RPM = 40.0  # a ringing shaft's aliased speed at shaft I (23.3 r/min measured, x1.7) [r/min]
ANGLE_RAD = 0.5  # shaft twist 4 x 0.065 rad + real-time skew 10 ms x 20 rad/s, at shaft I [rad]
OIL_TOL_K = 10.0  # oil leaving a clutch below its balance with plate estimate and sump, without a sensor fault [K]
OIL_KS = 2.0  # integral of the oil's deficit beyond OIL_TOL_K [K s]
OIL_FALL_K = 0.5  # a reading's fall beyond FALL_GAIN x the plate's passive cooling: two DBC steps + 0.3 K noise [K]
FALL_GAIN = 2.0  # the plate's passive cooling K_eff (T - T_sump) / C by the calibration, x2 for what it leaves out [1]
FALL_START_TAU = 8.0  # the fall check starts 8 oil time constants (startup_observer_s / 5 each) after the first cycle
SETTLE_TAU_LO = 0.75  # the oil's time constant is at least 0.75 x the calibration's startup_observer_s / 5 [1]
GAIN_FLOOR_C = 10.0  # a gain's relative error is taken at no colder reading than this (module docstring, 6) [degC]
OIL_FRAME_S = 0.1  # PLANT_OIL_TEMP's cycle time (DBC): a step hides in the plate's rise over one frame [s]
CLASS_ABS_K = 0.3  # an oil sensor's accuracy, IEC 60751 class B: +-(0.3 K + 0.005 |T|) (the calibration's
CLASS_REL = 0.005  # strategy.oil_accuracy_k is it at T_safe)
OIL_Q_K = 0.05  # half the DBC's 0.1-K step of PLANT_OIL_TEMP's temperatures [K]
START_PLATE_MAX_C = 150.0  # the hottest a plate may start (dsg_hil/sim/operating_range.py): a flagged clutch's start
_RPM_TO_RAD_S = math.pi / 30.0
CHECKED = ("P_CL", "P_CH", "ClutchInputSpeed", "T_OilCL", "T_OilCH")  # the signals checked, in this order


@dataclass(frozen=True)
class MatrixSteps:
    """What the plausibility checks and the controller's error budget take from the communication matrix in use
    (:meth:`ecu_stub.tcu_io.TcuIO.matrix_steps`, of its database and binding, in the TCU's units); the defaults are
    the shipped DBC's:

    * ``max_dt_s``: the longest receive timeout of the speed frames (VehicleSpeed's and the output speeds'): a
      cycle counts at most this long (:data:`~ecu_stub.plausibility.MAX_DT_S`);
    * ``oil_frame_s``: how often an oil temperature is sent anew, its frame's cycle time (times its pages, a
      multiplexed frame's) (:data:`OIL_FRAME_S`);
    * ``v_step_mps``: VehicleSpeed's step [m/s]; ``shaft_step_rpm``: the larger step of the two clutch output
      speeds; ``input_step_rpm``: ClutchInputSpeed's [r/min]."""

    max_dt_s: float = MAX_DT_S
    oil_frame_s: float = OIL_FRAME_S
    v_step_mps: float = 0.001
    shaft_step_rpm: float = 0.1
    input_step_rpm: float = 0.1


def oil_accuracy_at(T_c: float) -> float:
    """An oil sensor's accuracy at ``T_c`` [K]: IEC 60751 class B (module docstring, 5)."""
    return CLASS_ABS_K + CLASS_REL * abs(T_c)


def keyon_tolerance_k(T_hi_c: float) -> float:
    """The most two healthy oil sensors read one temperature apart at key-on [K], at the highest reading ``T_hi_c``:
    2 a(T) + 2 q (module docstring, 5)."""
    return 2.0 * oil_accuracy_at(T_hi_c) + 2.0 * OIL_Q_K


def settle_factor(prev_s: float, span_s: float, tau_s: float) -> float:
    """A settling reading's change over ``span_s`` per unit of its change over the ``prev_s`` before, for an
    exponential approach with time constant ``tau_s`` (module docstring, 6): e^(-a) (1 - e^(-b)) / (1 - e^(-a)),
    a = prev_s / tau_s, b = span_s / tau_s; e^(-a) for equal spans."""
    a, b = math.exp(-prev_s / tau_s), math.exp(-span_s / tau_s)
    return a * (1.0 - b) / (1.0 - a)


def keyon_undetected_k(T_hi_c: float) -> float:
    """The most a pack's oil reading may be low and pass the key-on check [K], with one of the other two healthy:
    the tolerance + that sensor's a(T) + the reading's own half step (module docstring, 5)."""
    return keyon_tolerance_k(T_hi_c) + oil_accuracy_at(T_hi_c) + OIL_Q_K


@dataclass(slots=True)
class PressureCheck:
    """One clutch's measured pressure vs the lag of the TCU's own command (module docstring, 1). ``lag_s``: the
    calibration's ``strategy.hydraulic_lag_s``; ``q_mpa``: half a DBC step of the measurement plus the command's."""

    lag_s: float
    q_mpa: float
    model_mpa: float | None = None  # the modelled pressure at the last update [MPa]
    check: Sustained = field(default_factory=lambda: Sustained(P_IMPULSE_MPA_S))

    def update(self, measured: float, cmd: float, dt: float, now: float, elapsed: float | None = None
               ) -> tuple[bool, float]:
        """One cycle: ``cmd`` the command sent the cycle before, held for ``elapsed`` [s] (default ``dt``; ``dt``
        counts in the CUSUM). (failing, the pressure to use [MPa])."""
        m = self.model_mpa
        if m is None:
            m = measured
        else:
            m = cmd + (m - cmd) * math.exp(-(dt if elapsed is None else elapsed) / self.lag_s)
        self.model_mpa = m
        abs_measured, abs_m = abs(measured), abs(m)  # (max() written out, here and below: the same floats)
        tol = self.q_mpa + P_ABS_MPA + P_REL * (abs_m if abs_m > abs_measured else abs_measured)
        failing = self.check.update(measured - m, tol, dt, now)
        return failing, max(measured, m) if failing else measured


@dataclass(slots=True)
class InputSpeedCheck:
    """ClutchInputSpeed vs EngineSpeed / i_a (module docstring, 2); speeds in r/min, ``q_rpm`` half DBC steps."""

    input_ratio: float
    q_rpm: float
    check: Sustained = field(default_factory=lambda: Sustained(ANGLE_RAD))

    def update(self, clutch_in: float, engine: float, dt: float, now: float) -> tuple[bool, float]:
        """(failing, the clutch input speed to use [r/min])."""
        via_engine = engine / self.input_ratio
        abs_in, abs_via = abs(clutch_in), abs(via_engine)
        tol = self.q_rpm + N_ABS_RPM + N_REL * (abs_via if abs_via > abs_in else abs_in)
        failing = self.check.update((clutch_in - via_engine) * _RPM_TO_RAD_S, tol * _RPM_TO_RAD_S, dt, now)
        return failing, max(clutch_in, via_engine) if failing else clutch_in


@dataclass(slots=True)
class SettleCheck:
    """The oil leaving a pack while it settles after key-on (module docstring, 6): each change of the reading (in
    whole oil frames) against the one before, carried by an exponential of time constant between
    :data:`SETTLE_TAU_LO` x ``tau_s`` and ``tau_s``, and, while no friction heat can come (``quiet_s``, the
    start-up observer's window: the TCU does not creep), three changes in a row against a geometric sequence and a
    fall against stopping dead. What each change may have hidden, per degC of its reading, is :attr:`ratio`."""

    tau_s: float  # the calibration's time constant of the oil in a pack (startup_observer_s / 5) [s]
    frame_s: float  # the oil frame's refresh [s]
    quiet_s: float  # no friction heat before this, after the first reading [s]
    start: float | None = None  # the first reading's time [s]
    last_c: float = 0.0  # the reading at the last change [degC]
    changed_at: float = 0.0  # the last change's time (a frame without a change counts as one of 0 K) [s]
    changes: list[float] = field(default_factory=list)  # the changes so far [K] (+ a rise)
    spans: list[int] = field(default_factory=list)  # each one's span [oil frames]
    hides: list[float] = field(default_factory=list)  # the step each may hide [K] (inf: not checked)
    temps: list[float] = field(default_factory=list)  # the reading after each [degC]
    k: float = 0.0  # the excess beyond what a settling reading does, a CUSUM [K]
    largest: float = 0.0  # its largest value (how close a run without a sensor fault came)
    failed: bool = False  # it passed OIL_FALL_K (latched by the caller)
    ratio: float = 0.0  # the largest of hides / reading [1 per degC] (GAIN_FLOOR_C the least reading)

    def update(self, oil: float, cooling_k_s: float, now: float) -> bool:
        """One cycle: the reading ``oil`` [degC] and the plate's largest passive cooling ``cooling_k_s`` [K/s]
        (FALL_GAIN x K_eff (T - T_sump) / C). Returns True once failed."""
        if self.start is None:
            self.start, self.changed_at, self.last_c = now, now, oil
            return False
        frame = self.frame_s
        frames = round((now - self.changed_at) / frame)
        if oil == self.last_c:
            if frames >= 2:  # a frame passed without a change: a change of 0 K one frame after the last
                self._change(0.0, 1, oil, cooling_k_s, self.changed_at + frame)
            return self.failed
        self._change(oil - self.last_c, frames if frames > 1 else 1, oil, cooling_k_s, now)
        self.last_c = oil
        return self.failed

    def _change(self, c: float, span: int, oil: float, cooling_k_s: float, at: float) -> None:
        """Judge the change ``c`` [K] over ``span`` frames, ending at ``at`` [s]."""
        changes, spans, hides = self.changes, self.spans, self.hides
        quiet = at - (self.start if self.start is not None else at) < self.quiet_s
        q = 2.0 * OIL_Q_K + cooling_k_s * span * self.frame_s  # a change's error: two half steps, the plate's drift
        hide, excess = math.inf, -math.inf
        if changes:
            prev, prev_span = changes[-1], spans[-1]
            hi = settle_factor(prev_span * self.frame_s, span * self.frame_s, self.tau_s)
            lo = settle_factor(prev_span * self.frame_s, span * self.frame_s, SETTLE_TAU_LO * self.tau_s)
            slack = q * (1.0 + hi)
            least, most = (prev * hi, prev * lo) if prev < 0.0 else (prev * lo, prev * hi)
            excess = least - slack - c  # moved lower than a settling reading can: stepped low now
            if quiet:  # moved higher: the change before stepped low (a fall that stops dead, a rise grown)
                higher = c - most - slack
                if higher > excess:
                    excess = higher
                if c == 0.0 and prev < 0.0 and len(changes) == 1:  # the first change alone: a lone step's bound
                    bound = (slack + OIL_FALL_K) / lo
                    if bound < hides[0]:
                        hides[0] = bound
            hide = (hi - lo) * abs(prev) + slack + OIL_FALL_K
            if len(changes) >= 2 and quiet and span == prev_span == spans[-2] == 1:
                older = changes[-2]
                if older * prev > 0.0 and prev * c > 0.0 and abs(prev) > q:  # three in a row, one way: c2^2 = c1 c3
                    dev = (prev * prev - older * c) / (2.0 * abs(prev))  # the step of the middle that explains it
                    tol = q * (2.0 * abs(prev) + abs(older) + abs(c)) / (2.0 * abs(prev))
                    geometric = abs(dev) - tol
                    if geometric > excess:
                        excess = geometric
                    verified = tol + OIL_FALL_K
                    if verified < hides[-1]:
                        hides[-1] = verified  # the middle one, checked with the sensitivity 1
                    if len(changes) == 2:  # the first, an outer one: a step in it moves dev by R / 2 of it
                        outer = 2.0 * verified * abs(older) / abs(prev)
                        if outer < hides[0]:
                            hides[0] = outer
        elif span > 1:
            hide, excess = q + OIL_FALL_K, -c - q  # the first change after a settled frame or more: any fall
        k = self.k + excess if excess > -math.inf else self.k
        self.k = k = k if k > 0.0 else 0.0
        if k > self.largest:
            self.largest = k
        if k > OIL_FALL_K:
            self.failed = True
        changes.append(c)
        spans.append(span)
        hides.append(hide)
        self.temps.append(oil)
        self.changed_at = at
        ratio = 0.0
        for h, T in zip(hides, self.temps):
            if h < math.inf:
                r = h / (T if T > GAIN_FLOOR_C else GAIN_FLOOR_C)
                if r > ratio:
                    ratio = r
        self.ratio = ratio


@dataclass(slots=True)
class OilCheck:
    """The oil leaving one clutch vs its balance with the plate estimate and the sump, and its fall vs the plate's
    fastest passive cooling (module docstring, 3 and 4); degC. ``sump_share``: cooling / (K + cooling) of that
    clutch's calibration; ``cooling_per_s``: K cooling / (K + cooling) / C (0: no fall check); ``fall_from_s``:
    the fall check's start after the first cycle [s]."""

    sump_share: float
    cooling_per_s: float = 0.0
    fall_from_s: float = 0.0
    settle_tau_s: float = 0.0  # the oil's time constant by the calibration (0: no settling check) [s]
    frame_s: float = OIL_FRAME_S  # the oil frame's refresh: the first change within 1.5 of it is key-on's [s]
    check: Sustained = field(default_factory=lambda: Sustained(OIL_KS, one_sided=True))
    first_now: float | None = None  # the first cycle [s]
    last_oil: float | None = None  # the reading of the last cycle [degC]
    fall_k: float = 0.0  # the reading's fall beyond FALL_GAIN x the passive cooling, a one-sided CUSUM [K]
    largest_fall_k: float = 0.0  # its largest value (how close a run without a sensor fault came)
    fell_at: float | None = None  # when it passed OIL_FALL_K: the reading is not trusted again (a latched fault)
    keyon_failed: bool = False  # read too low at key-on (module docstring, 5): not trusted in this operation cycle
    keyon_at: float | None = None  # the key-on check's time [s]
    start_c: float = START_PLATE_MAX_C  # the plate's hottest credible start: START_PLATE_MAX_C or the key-on readings
    settle: SettleCheck | None = None  # the settling check (module docstring, 6), with settle_tau_s

    def __post_init__(self) -> None:
        if self.settle_tau_s > 0.0:
            self.settle = SettleCheck(self.settle_tau_s, self.frame_s, 5.0 * self.settle_tau_s)

    @property
    def undetected_ratio(self) -> float:
        """The largest oil step the settling check let through, per degC of the reading [1] (0: no such check)."""
        return self.settle.ratio if self.settle is not None else 0.0

    def update(self, oil: float, sump: float, plate: float | None, dt: float, now: float) -> tuple[bool, float]:
        """(failing, the oil temperature to use [degC]); ``plate``: the TCU's estimate, None before it has one (then
        nothing is checked)."""
        balance = oil if plate is None else plate + self.sump_share * (sump - plate)
        settle = self.settle
        if settle is not None and settle.start is None:  # the first reading, with or without a plate estimate
            settle.update(oil, 0.0, now)
        failing = self.check.update(balance - oil, OIL_TOL_K, dt, now)
        if plate is not None and self.cooling_per_s > 0.0:
            if self.first_now is None:
                self.first_now = now
            last, self.last_oil = self.last_oil, oil
            if now - self.first_now < self.fall_from_s:
                if settle is not None:
                    above = plate - sump
                    if settle.update(oil, FALL_GAIN * self.cooling_per_s * (above if above > 0.0 else 0.0), now) \
                            and self.fell_at is None:
                        self.fell_at = now
                    if settle.largest > self.largest_fall_k:
                        self.largest_fall_k = settle.largest
            elif last is not None:
                above = plate - sump  # the plate's passive cooling, max() written out
                fall = self.fall_k + (last - oil) - FALL_GAIN * self.cooling_per_s * (above if above > 0.0 else 0.0) \
                    * dt
                self.fall_k = fall = fall if fall > 0.0 else 0.0
                if fall > self.largest_fall_k:
                    self.largest_fall_k = fall
                if fall > OIL_FALL_K and self.fell_at is None:
                    self.fell_at = now
            failing = failing or self.fell_at is not None
        if self.keyon_failed:  # the plate predicted adiabatic from its hottest credible start (module docstring, 5)
            start = self.start_c
            if plate is None or self.keyon_at is None or now - self.keyon_at < self.fall_from_s:
                return True, max(oil, sump, start)  # (the start-up observer's estimate is not fed back to it)
            return True, max(oil, sump, plate, start)
        return failing, max(oil, sump, plate if plate is not None else sump) if failing else oil


@dataclass(slots=True)
class SensorChecks:
    """The three checks of both clutches, run each control cycle by :meth:`update`; ``last_now`` and the commands
    of the last cycle (:meth:`commanded`) carried between cycles."""

    lag_s: float
    q_p_mpa: float
    input_ratio: float
    q_n_rpm: float
    sump_share: dict[str, float]  # by clutch: cooling / (K + cooling) of the calibration
    cooling_per_s: dict[str, float] = field(default_factory=dict)  # by clutch: K_eff / C (none: no fall check)
    fall_from_s: float = 0.0  # the fall check's start after the first cycle [s]
    settle_tau_s: float = 0.0  # the oil's time constant by the calibration: the settling check before (0: none) [s]
    max_dt_s: float = MAX_DT_S  # a cycle counts at most this long (MatrixSteps.max_dt_s) [s]
    oil_frame_s: float = OIL_FRAME_S  # the oil frame's refresh: the key-on check's first frame (MatrixSteps) [s]
    last_now: float | None = None
    keyon_checked: bool = False  # the key-on check was made (the first cycle came with the first oil frame)
    cmd_mpa: dict[str, float] = field(default_factory=lambda: {"CL": 0.0, "CH": 0.0})
    pressure: dict[str, PressureCheck] = field(init=False)
    speed: InputSpeedCheck = field(init=False)
    oil: dict[str, OilCheck] = field(init=False)

    def __post_init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the history (a restarted run)."""
        self.pressure = {c: PressureCheck(self.lag_s, self.q_p_mpa) for c in ("CL", "CH")}
        self.speed = InputSpeedCheck(self.input_ratio, self.q_n_rpm)
        self.oil = {c: OilCheck(self.sump_share[c], self.cooling_per_s.get(c, 0.0), self.fall_from_s,
                                self.settle_tau_s, self.oil_frame_s) for c in ("CL", "CH")}
        self.last_now, self.cmd_mpa, self.keyon_checked = None, {"CL": 0.0, "CH": 0.0}, False

    def commanded(self, P_CL_mpa: float, P_CH_mpa: float) -> None:
        """The commands the TCU sends this cycle (the pressures' model follows them from the next)."""
        self.cmd_mpa["CL"], self.cmd_mpa["CH"] = P_CL_mpa, P_CH_mpa

    def update(self, values: dict[str, float], plate: dict[str, float] | None, now: float) -> list[str]:
        """One cycle at ``now`` on the decoded ``values`` (by signal name: P_CL, P_CH, ClutchInputSpeed,
        EngineSpeed, T_OilCL, T_OilCH, T_Sump), which it replaces in place by the values to use where a check
        fails; ``plate`` the TCU's plate estimates (None before it has one). Returns the failing signals."""
        *used, failing = self.check(values["P_CL"], values["P_CH"], values["ClutchInputSpeed"], values["EngineSpeed"],
                                    values["T_OilCL"], values["T_OilCH"], values["T_Sump"], plate, now)
        values.update(zip(CHECKED, used))
        return failing

    def check(self, P_CL: float, P_CH: float, clutch_in: float, engine: float, T_oil_CL: float, T_oil_CH: float,
              T_sump: float, plate: dict[str, float] | None, now: float
              ) -> tuple[float, float, float, float, float, list[str]]:
        """:meth:`update` on the values one by one (a cycle's, without a dict): the values to use of the checked
        signals (:data:`CHECKED`: P_CL, P_CH, ClutchInputSpeed, T_OilCL, T_OilCH) and the failing ones."""
        last, self.last_now = self.last_now, now
        elapsed = 0.0 if last is None else now - last
        max_dt = self.max_dt_s
        dt = max_dt if max_dt < elapsed else elapsed  # min(elapsed, max_dt_s)
        cmd, pressure, oil = self.cmd_mpa, self.pressure, self.oil
        if last is None and now < self.oil_frame_s:
            self.keyon(T_oil_CL, T_oil_CH, T_sump, now)
        bad_P_CL, P_CL = pressure["CL"].update(P_CL, cmd["CL"], dt, now, elapsed)
        bad_P_CH, P_CH = pressure["CH"].update(P_CH, cmd["CH"], dt, now, elapsed)
        bad_in, clutch_in = self.speed.update(clutch_in, engine, dt, now)
        bad_T_CL, T_oil_CL = oil["CL"].update(T_oil_CL, T_sump, None if plate is None else plate["CL"], dt, now)
        bad_T_CH, T_oil_CH = oil["CH"].update(T_oil_CH, T_sump, None if plate is None else plate["CH"], dt, now)
        failing = [name for name, bad in zip(CHECKED, (bad_P_CL, bad_P_CH, bad_in, bad_T_CL, bad_T_CH)) if bad] \
            if bad_P_CL or bad_P_CH or bad_in or bad_T_CL or bad_T_CH else []
        return P_CL, P_CH, clutch_in, T_oil_CL, T_oil_CH, failing

    def keyon(self, T_oil_CL: float, T_oil_CH: float, T_sump: float, now: float = 0.0) -> None:
        """The key-on check (module docstring, 5) on the first frame's oil temperatures: a pack's reading more than
        :func:`keyon_tolerance_k` below the highest of the three is not trusted again in this operation cycle."""
        self.keyon_checked = True
        hi = T_oil_CL if T_oil_CL > T_oil_CH else T_oil_CH
        hi = hi if hi > T_sump else T_sump
        tol = keyon_tolerance_k(hi)
        for c, T in (("CL", T_oil_CL), ("CH", T_oil_CH)):
            check = self.oil[c]
            check.start_c, check.keyon_at = hi if hi > START_PLATE_MAX_C else START_PLATE_MAX_C, now
            if hi - T > tol:
                check.keyon_failed = True
