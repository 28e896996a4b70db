"""Plausibility of the vehicle speed: ``PLANT_VEHICLE.VehicleSpeed`` voted against the two clutch-output speeds.

A frame with a valid CRC and counter can still carry a wrong value (a stuck or offset sensor): the safety sweep
found ``VehicleSpeed`` stuck at 0 for 3.1 s while creeping downhill, and the speed controller, believing the
vehicle stopped, drove it to 0.97 m/s with 0.37 m/s requested. The TCU has two redundant measures of the same
speed from the DBC: ``PLANT_SPEEDS.CLOutputSpeed`` and ``CHOutputSpeed``. Both sub-gearboxes keep their gear
engaged during creep (the strategy hands the load over between the clutches, Fig. 7), so each output turns with the
wheels: v = r_c omega_c, with r_c the calibration's ``clutch.CL/CH.speed_ratio_m`` (m/s per rad/s). The clutch
*input* speed is never compared: it differs from the outputs by the slip, legitimately.

**Tolerance.** Two measures a, b of the vehicle speed (in m/s) differ, without a sensor fault, by at most

    tol = q_a + q_b + REL_TOL * max(|a|, |b|)                         (:func:`tolerance_mps`)

plus what the driveline's torsional compliance adds while a torque changes:

* q: half a DBC step of each signal (its resolution): VehicleSpeed 0.001 m/s -> 0.5 mm/s; a shaft speed
  0.1 r/min -> 0.05 r/min x pi/30 x r_c = 0.18 mm/s (CL), 0.31 mm/s (CH).
* ``REL_TOL`` = 3 %: the speed ratios are identified (median of v / omega, 0.04-0.07 % off Table I here), but a
  real wheel's rolling radius changes by about 3 % between a new and a worn tyre and with load and inflation.
* Compliance: the shafts between a clutch output and the wheel are springs, so while a torque changes their speeds
  differ by the twist rates (modes near 90 Hz, lightly damped): a twist *rate* has no bound worth using, but the
  twist has, so the check bounds the *distance* the two measures travel apart. Over any interval, without a
  sensor fault,

      integral of (a - b - tol) dt  <=  TWIST_M + SKEW_M = 40 mm   (and with a, b swapped; :data:`DISTANCE_M`)

  ``TWIST_M`` = 30 mm, the largest change of the driveline's twist as distance at the wheel (Table I): the
  wheel-side stiffnesses are k_a3 = K_a3 (i_b / r_w)^2 = 65114 x (3.818 / 0.1935)^2 = 2.54e7 N/m (shaft III) and
  k_a2 = K_a2 (i_b i_1 / r_w)^2 = 110088 x (3.818 x 0.925 / 0.1935)^2 = 3.67e7 N/m (each output's gear pair); the
  largest wheel forces of the clutches, mu k_geom P_max / r_c with mu <= 0.07 (the friction map), k_geom =
  0.027337 m^3 and P_max = 1.5 MPa (the DBC's command range), are CL 83.3 kN and CH 48.2 kN; so the CL path twists
  by at most (83.3 + 48.2) kN / k_a3 + 83.3 kN / k_a2 = 5.2 + 2.3 = 7.5 mm (the CH path less); a torque step may
  overshoot that by 2x and the twist swing from one sign to the other: 4 x 7.5 mm = 30 mm. ``SKEW_M`` = 10 mm:
  in real time the TCU holds PLANT_SPEEDS and PLANT_VEHICLE from frames up to one cycle (10 ms) apart, which
  shifts the travelled distances apart by at most 10 ms x the speed change over the interval, 1 m/s at creep
  speeds (in lock-step both are sampled at the same instant: 0).

  This integral is the debounce (:class:`PairCheck`: its largest value over the intervals ending now, a
  one-sided CUSUM per sign): a pair is *disagreeing* once it passes :data:`DISTANCE_M`; a stuck-at-zero
  VehicleSpeed at 0.37 m/s does so in about 0.11 s, one 10 mm/s over the tolerance in 4 s; an intermittent fault
  adds up. A cycle counts at most :data:`MAX_DT_S` (the DBC's 3-cycle receive timeout): after a gap in the frames
  the values held do not describe it.

**Reaction** (:class:`SpeedVoter`), a 2-out-of-3 vote as a real DCT does with its redundant speed sensors:

* VehicleSpeed is not disagreeing with at least one output speed: it is used as it is (``OK``; nothing changes).
* It disagrees with both, and the two output speeds do not disagree with each other: VehicleSpeed is faulty and
  replaced by the mean of the two shaft-derived speeds (``SUBSTITUTED``). The vehicle stays controlled on two
  plausible sensors; stopping it on a grade or in traffic would be a hazard of its own.
* All three pairs disagree: no speed can be trusted (``FAULT``): the TCU goes to its FAULT state (both clutches
  open, the brake requested), as for missing frames.

A pair stays disagreeing for :data:`HEAL_S` = 2 s after its distance last passed the bound (its integrals then
start afresh): a fault that persists passes it again sooner unless it is within 20 mm/s of the tolerance
(40 mm / 2 s), so such a sensor stays replaced, and a repaired one is trusted again 2 s later. A run without a
sensor fault never reaches the bound, so it gives the very same inputs, and frames, as without the check.

**An impossible step substitutes at once** (:func:`plausible_step`). The vote needs its 40 mm: a VehicleSpeed stuck
at 0 while creeping at 0.187 m/s took 0.15-0.2 s, in which the speed controller, believing the vehicle stopped,
tripled the clutch force: a light vehicle (5,086 kg on 0.1 rad, found by a 1,000-run sample of the safety space)
reached 0.759 m/s before the substitute brought it back. But VehicleSpeed is the speed of the vehicle's mass, the
most inert state of the driveline (the shafts ring, it does not), and without a brake nothing decelerates a vehicle
faster than the slope and the rolling resistance: dv/dt >= -g (sin a + f cos a) = -3.60 m/s^2 on the steepest grade
of the documented range (0.25 rad) with Table I's f = 0.123 (the clutches push forwards at creep speeds: the engine
turns faster than either output); :data:`A_COAST_MPS2` = 4 m/s^2 with 10 % for what that leaves out. Nothing
accelerates it faster than its tyres' grip, 1.2 g + g sin 0.25 (:data:`A_GRIP_MPS2` = 14.2 m/s^2). A step beyond
these between two PLANT_VEHICLE frames (their counter's step times the DBC's cycle: the plant's own clock, whatever
the bus delays; the control cycles' time if longer) is a sensor fault at once: VehicleSpeed is replaced by the shafts'
speed (``SUBSTITUTED``, if the shafts agree) from that cycle on, until the vote takes over or VehicleSpeed's distances
to both shafts are back to zero (at most :data:`HEAL_S`). Measured over bench/tcu_envelope.py's cases without a
brake, VehicleSpeed changes by at most 11 mm/s per cycle against 41 mm/s allowed: a run without a sensor fault gives
the same frames as before. A brake adds deceleration: the driver's pedal p (its largest over the last
:data:`BRAKE_SETTLE_S`) up to p times the calibration's ``vehicle.brake_decel_mps2`` (the service brakes' full torque
over the wheel radius and the lightest vehicle: 52.7 m/s^2; the plant's brake is a torque up to
``vehicle.M_brake_max`` that grip does not limit), so a 1 % drag allows 4.5 m/s^2; the TCU's own deceleration
request (TCU_CMD.DecelRequest, its largest over the last :data:`BRAKE_SETTLE_S`, + half its DBC step) allows that
much: the plant's brakes decelerate the vehicle by at most what is asked (the wheel torque m a r_w, less through the
rotating inertias); its full-brake request (TCU_STATUS.BrakeRequest, within :data:`BRAKE_SETTLE_S`) allows any, and
only the vote judges. Each largest over the last :data:`BRAKE_SETTLE_S` is every cycle's value of that window's
(:class:`PeakHold`), not only its last peak's.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from enum import Enum

__all__ = ["A_COAST_MPS2", "A_GRIP_MPS2", "BRAKE_SETTLE_S", "DISTANCE_M", "HEAL_S", "MAX_DT_S", "REL_TOL", "SKEW_M",
           "TWIST_M", "PairCheck", "PeakHold", "SpeedVoter", "Sustained", "Verdict", "plausible_step",
           "shaft_speed_mps", "tolerance_mps"]

TWIST_M = 0.030  # largest change of the driveline's twist, as distance at the wheel [m] (module docstring)
SKEW_M = 0.010  # real time: PLANT_SPEEDS and PLANT_VEHICLE up to one 10-ms cycle apart, 1 m/s of speed change [m]
DISTANCE_M = TWIST_M + SKEW_M  # what compliance and skew can put between two measures' travelled distances [m]
REL_TOL = 0.03  # rolling radius of a real tyre (wear, load, inflation) and the identified speed ratios [1]
HEAL_S = 2.0  # a pair is disagreeing this long after its distance last passed DISTANCE_M [s]
MAX_DT_S = 0.03  # a cycle counts at most the DBC's receive timeout (3 cycles of 10 ms) [s] (the shipped DBC's)
A_COAST_MPS2 = 4.0  # fastest deceleration without a brake: g (sin 0.25 + 0.123 cos 0.25) = 3.60, +10 % [m/s^2]
A_GRIP_MPS2 = 14.2  # fastest acceleration: the tyres' grip, 1.2 g, + g sin 0.25 [m/s^2]
BRAKE_SETTLE_S = 0.2  # a brake acts this long after its request or pedal ends (TCU_STATUS, DRIVER cycles) [s]
_RPM_TO_RAD_S = math.pi / 30.0
_EPS_S = 1e-9  # times are sums of float cycle times: 50 x 10 ms may come out a hair under 0.5 s
_HEALED_S = HEAL_S - _EPS_S  # failing while the bound was passed less than this ago [s]


class Verdict(Enum):
    """The reaction: use VehicleSpeed, use the shaft-derived speed instead, or a sensor fault."""

    OK = "ok"
    SUBSTITUTED = "substituted"
    FAULT = "fault"


def shaft_speed_mps(out_rpm: float, speed_ratio_m: float) -> float:
    """Vehicle speed [m/s] from a clutch output speed [r/min]: v = r_c omega_c (r_c in m/s per rad/s)."""
    return speed_ratio_m * out_rpm * _RPM_TO_RAD_S


def tolerance_mps(a: float, b: float, q_a: float, q_b: float) -> float:
    """Largest steady difference [m/s] of two measures ``a``, ``b`` of the vehicle speed without a sensor fault:
    half-step resolutions ``q_a`` + ``q_b`` and :data:`REL_TOL` of the larger speed (module docstring)."""
    return q_a + q_b + REL_TOL * max(abs(a), abs(b))


@dataclass(slots=True)
class PeakHold:
    """The largest value added over the last ``window_s`` [s] (a brake acts that long after its request or pedal
    ends), 0 if none: the window's values, each with its time, as a decreasing queue (a value hides the older ones it
    is not smaller than), so that a peak that ages out leaves the largest of the values after it."""

    window_s: float
    _seen: deque[tuple[float, float]] = field(default_factory=deque)

    def add(self, now: float, value: float) -> None:
        """``value`` at ``now`` [s] (times not decreasing); what has aged out dropped (the queue holds one window)."""
        seen = self._seen
        while seen and seen[-1][1] <= value:
            seen.pop()
        seen.append((now, value))
        self._age(now)

    def peak(self, now: float) -> float:
        """The largest value added from ``now - window_s`` on (0 if none)."""
        self._age(now)
        seen = self._seen
        return seen[0][1] if seen else 0.0

    def _age(self, now: float) -> None:
        seen = self._seen
        while seen and now - seen[0][0] > self.window_s + _EPS_S:
            seen.popleft()

    def clear(self) -> None:
        self._seen.clear()


def plausible_step(dv_mps: float, span_s: float, q_mps: float, brake_mps2: float = 0.0) -> bool:
    """A change ``dv_mps`` of VehicleSpeed over ``span_s`` [s] of the plant's time that a vehicle can make:
    -(:data:`A_COAST_MPS2` + ``brake_mps2``) span - 2 q <= dv <= :data:`A_GRIP_MPS2` span + 2 q, with ``q`` half a
    DBC step and ``brake_mps2`` the most deceleration the brake may add (module docstring)."""
    return -((A_COAST_MPS2 + brake_mps2) * span_s + 2.0 * q_mps) <= dv_mps <= A_GRIP_MPS2 * span_s + 2.0 * q_mps


@dataclass(slots=True)
class Sustained:
    """The debounce of every plausibility check here and in :mod:`ecu_stub.sensor_checks`: one-sided CUSUMs of a
    difference beyond its tolerance: ``over[0]`` = the largest integral of (difference - tol) over the intervals
    ending now, ``over[1]`` that of (-difference - tol) (only the first if ``one_sided``): a difference that swings
    from one sign to the other (a shaft ringing) adds up on neither, a sustained one on one. Passing ``bound`` sets
    ``last_over`` and starts both afresh; :meth:`failing` for :data:`HEAL_S` after that."""

    bound: float
    one_sided: bool = False
    over: list[float] = field(default_factory=lambda: [0.0, 0.0])
    last_over: float | None = None
    largest: float = 0.0  # the largest integral seen (how close a run without a sensor fault came)

    def update(self, difference: float, tol: float, dt: float, now: float) -> bool:
        """One cycle ``dt`` [s] long, ending at ``now`` [s]; returns :meth:`failing`. (Every check, every cycle: the
        max() of each integral with 0, of ``largest`` and :meth:`failing` written out, the same floats.)"""
        over = self.over
        up = over[0] + (difference - tol) * dt
        up = up if up > 0.0 else 0.0
        down = over[1]
        if not self.one_sided:
            down += (-difference - tol) * dt
            down = down if down > 0.0 else 0.0
        largest = self.largest
        if up > largest:
            largest = up
        if down > largest:
            largest = down
        self.largest = largest
        if up > self.bound or down > self.bound:
            self.last_over, up, down = now, 0.0, 0.0
        over[0], over[1] = up, down
        last = self.last_over
        return last is not None and now - last < _HEALED_S

    def failing(self, now: float) -> bool:
        """The bound passed less than :data:`HEAL_S` ago."""
        return self.last_over is not None and now - self.last_over < _HEALED_S


@dataclass(slots=True)
class PairCheck:
    """Two measures of the vehicle speed with half-step resolutions ``q_a``, ``q_b`` [m/s]: a :class:`Sustained`
    of a - b beyond the tolerance with the bound :data:`DISTANCE_M` (``over_m[0]`` = the largest integral of
    (a - b - tol) over any interval ending now, ``over_m[1]`` the same of (b - a - tol): each is the bound's
    left-hand side, so a pair without a sensor fault keeps both within it). The pair is :meth:`disagreeing` for
    :data:`HEAL_S` after its distance last passed the bound (``last_over``)."""

    q_a: float
    q_b: float
    check: Sustained = field(default_factory=lambda: Sustained(DISTANCE_M))

    @property
    def over_m(self) -> list[float]:
        return self.check.over

    @property
    def last_over(self) -> float | None:
        """When the distance last passed DISTANCE_M [s]."""
        return self.check.last_over

    def update(self, a: float, b: float, dt: float, now: float) -> bool:
        """One cycle ``dt`` [s] long, ending at ``now`` [s]; returns :meth:`disagreeing`."""
        abs_a, abs_b = abs(a), abs(b)  # tolerance_mps written out (the same operations: three pairs every cycle)
        tol = self.q_a + self.q_b + REL_TOL * (abs_b if abs_b > abs_a else abs_a)
        return self.check.update(a - b, tol, dt, now)

    def disagreeing(self, now: float) -> bool:
        """The distance passed :data:`DISTANCE_M` less than :data:`HEAL_S` ago."""
        return self.check.failing(now)


@dataclass(slots=True)
class SpeedVoter:
    """The 2-out-of-3 vote over time (module docstring): :meth:`update` each control cycle with the decoded speeds
    gives the :class:`Verdict` and the vehicle speed to use. ``speed_ratio_*_m``: the calibration's
    ``clutch.CL/CH.speed_ratio_m``; ``v_step_mps``, ``shaft_step_rpm``: the DBC's scale of VehicleSpeed and of the
    output speeds; ``v_cycle_s``, ``counter_modulus``, ``max_dt_s``: VehicleSpeed's frame's cycle time and counter,
    and the speed frames' receive timeout (the matrix's: :class:`~ecu_stub.sensor_checks.MatrixSteps`)."""

    speed_ratio_cl_m: float
    speed_ratio_ch_m: float
    v_step_mps: float
    shaft_step_rpm: float
    v_cycle_s: float = 0.01  # PLANT_VEHICLE's cycle time (DBC) [s]
    counter_modulus: int = 16
    max_dt_s: float = MAX_DT_S  # a cycle counts at most the speed frames' receive timeout (the matrix's) [s]
    verdict: Verdict = Verdict.OK
    last_now: float | None = None
    pairs: tuple[PairCheck, PairCheck, PairCheck] = field(init=False)  # (v, CL), (v, CH), (CL, CH)
    last_v: tuple[float, int, float] | None = None  # the last VehicleSpeed taken: (value, frame counter, time)
    stepped_at: float | None = None  # when VehicleSpeed last made an impossible step (:func:`plausible_step`)
    outvoted: str = ""  # "CL" / "CH": that output speed disagrees with VehicleSpeed and the other, which agree

    def __post_init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the history (a restarted run)."""
        half = 0.5 * self.shaft_step_rpm * _RPM_TO_RAD_S
        q_v, q_cl, q_ch = 0.5 * self.v_step_mps, half * self.speed_ratio_cl_m, half * self.speed_ratio_ch_m
        self.pairs = (PairCheck(q_v, q_cl), PairCheck(q_v, q_ch), PairCheck(q_cl, q_ch))
        self.verdict, self.last_now, self.last_v, self.stepped_at = Verdict.OK, None, None, None
        self.outvoted = ""

    def _stepped(self, v_mps: float, counter: int | None, now: float, brake_mps2: float) -> bool:
        """True if VehicleSpeed stepped impossibly since its last frame (:func:`plausible_step`): the span is the
        frames' counter step times :attr:`v_cycle_s` (the plant's clock), or the time since, if longer."""
        last, self.last_v = self.last_v, (v_mps, -1 if counter is None else counter, now)
        if last is None:
            return False
        v_last, counter_last, t_last = last
        if counter is not None:
            frames = (counter - counter_last) % self.counter_modulus
            if frames == 0:  # no new frame: the value held
                self.last_v = last
                return False
        else:
            frames = 1
        span = max(frames * self.v_cycle_s, now - t_last)
        return not plausible_step(v_mps - v_last, span, 0.5 * self.v_step_mps, brake_mps2)

    def update(self, v_mps: float, cl_out_rpm: float, ch_out_rpm: float, now: float, counter: int | None = None,
               brake_mps2: float = 0.0) -> tuple[Verdict, float]:
        """One cycle at ``now`` [s]: (verdict, the vehicle speed to use [m/s]): ``v_mps`` itself unless the verdict
        is SUBSTITUTED (then the mean of the two shaft-derived speeds). The cycle's length counts up to
        :attr:`max_dt_s` (:data:`MAX_DT_S` on the shipped DBC; after a longer gap, e.g. FAULT on missing frames, the
        values held did not describe it).
        ``counter``: PLANT_VEHICLE's frame counter (None: every cycle a new frame); ``brake_mps2``: the most
        deceleration a brake may add now (``math.inf``: any; module docstring)."""
        if self._stepped(v_mps, counter, now, brake_mps2):
            self.stepped_at = now
        last, self.last_now = self.last_now, now
        dt = 0.0 if last is None else now - last
        max_dt = self.max_dt_s
        dt = max_dt if max_dt < dt else dt  # min(dt, max_dt_s)
        v_cl = self.speed_ratio_cl_m * cl_out_rpm * _RPM_TO_RAD_S  # shaft_speed_mps of each, written out
        v_ch = self.speed_ratio_ch_m * ch_out_rpm * _RPM_TO_RAD_S
        with_cl, with_ch, shafts = self.pairs
        off_cl, off_ch = with_cl.update(v_mps, v_cl, dt, now), with_ch.update(v_mps, v_ch, dt, now)
        off_shafts = shafts.update(v_cl, v_ch, dt, now)
        self.outvoted = "CL" if off_cl and off_shafts and not off_ch else \
            "CH" if off_ch and off_shafts and not off_cl else ""
        if not (off_cl and off_ch):
            stepped = self.stepped_at
            if stepped is not None:  # an impossible step, not yet judged by the vote: the shafts' speed if they agree
                if not off_shafts and now - stepped < _HEALED_S and max(with_cl.check.over) > 0.0 \
                        and max(with_ch.check.over) > 0.0:
                    self.verdict = Verdict.SUBSTITUTED
                    return self.verdict, 0.5 * (v_cl + v_ch)
                self.stepped_at = None
            self.verdict = Verdict.OK
            return self.verdict, v_mps
        if off_shafts:
            self.verdict = Verdict.FAULT
            return self.verdict, v_mps
        self.verdict = Verdict.SUBSTITUTED
        return self.verdict, 0.5 * (v_cl + v_ch)
