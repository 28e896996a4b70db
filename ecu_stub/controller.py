"""The creep strategy of the paper (Fig. 7, Section V) as ``CreepController.update(inputs, now) -> outputs``.

No bus, no clock: time is passed in, so the strategy is tested with a fake clock and can run behind any bus.

* IDLE: both clutches open. Hold: the TCU requests the brake while the vehicle stands, and while it moves with
  nobody braking it (a creep request withdrawn without the brake stops and holds the vehicle: the clutches ramp out
  over ``stop_release_s`` while the request reaches the brakes); it leaves a moving vehicle to the driver's brake
  only, unless his pedal, pressed, does not hold it (over its target by the drivability band and speeding up: a
  light pedal downhill), which the TCU overrules with its brake request until the vehicle stands. Creep requested
  at a desired speed of 0 is a stand: held, no launch. The hold ends when a launch's pre-fill carries the vehicle.
* ENGAGE: on the creep request, the on-coming clutch (CL first) is filled at once to the pressure that carries the
  pre-fill's wheel force (:meth:`CreepController.prefill_force`: for the grade the accelerometer read at the
  standstill, the heaviest vehicle until a creep settled or stood still has shown this one's weight); the brake
  request is dropped when the measured pressure has reached it (never on a pressure the runner's plausibility check
  found implausible: :mod:`ecu_stub.sensor_checks`).
* CREEP: a PI controller on vehicle speed sets the wheel force (its reference reaches the desired speed along a
  ramp of ``launch.accel_mps2``, so a launch or a new desired speed is no step); the active clutch's pressure
  follows from the TCU's model of that clutch (torque = mu(T, slip, P) k_geom P, the speed ratio to the wheel,
  efficiency).
* HANDOVER: a torque handover as in a DCT shift: over ``handover_time_s`` the on-coming clutch takes a growing
  share x of the wheel force and the off-going the rest (1 - x), each converted to pressure by its own model,
  while the speed controller keeps running; if the thermal monitor releases the off-going clutch faster than its
  share, the on-coming one takes the force it no longer gives.
* Downhill (no clutch can brake at creep speed: both slip forwards) the speed controller's wheel force goes negative
  and its negative part is asked of the brakes as a deceleration (TCU_CMD.DecelRequest: the force over the nominal
  mass ``vehicle.m_kg``, up to ``speed.decel_max_mps2``; :meth:`decel_request`), as a DCT asks the ESC: the vehicle
  holds its target speed. Only if it is still ``speed.overspeed_fraction`` over its target and speeding up with
  that request at its limit and both clutches open (brakes that do not follow it) is the full brake requested
  (TCU_STATUS.BrakeRequest), until it stands.
* The handover starts when the active clutch's *predicted* plate temperature reaches its limit
  ``T_safe - prediction_error_k - dT_crossover`` (``dT_crossover``: the heat still coming into the off-going plate
  while its share ramps out and its pressure lags, at the friction power it would have through the crossover
  (the vehicle carried to its desired speed: not a launch's transient power), but at least the monitor's
  worst-case heat of a fastest release, so that the monitor can always release it in time; see :meth:`limit`),
  or when the prediction has stayed within ``dwell_band_k`` under the limit for ``dwell_time_s``.
  The other clutch takes over if it is predicted ``takeover_headroom_k`` under its limit, the limit taken at the
  power it will have once it carries the wheel force (its own gear's torque, :meth:`takeover_heat`), not the
  power of the moment; otherwise STOPPED_OVERHEAT. If it may but cannot give the wheel force demanded
  (:meth:`carries`), the active clutch carries on past its handover limit (whose crossover allowance is then moot)
  until the thermal monitor stops the vehicle: the plate is used up to the monitor's bound, not given up early.
* A clutch that cannot carry the vehicle (CREEP with the wheel force at the clutch's capacity and the vehicle under
  half its target for ``STALL_S``: CH's gear needs 1.73 times CL's torque, so a heavy vehicle on a steep grade is
  beyond CH at its pressure limit) hands over as at its limit: to the other clutch if that one may take over and
  can carry, otherwise STOPPED_OVERHEAT (the vehicle held, not left standing under a slipping clutch).
* Clutches not following their commands (a measured pressure implausible: a dead valve, or the commands lost on
  the bus): with the vehicle standing, rolling back or running away, the brake is requested and held; the speed
  controller's integral is held meanwhile; the creep resumes as a launch (ENGAGE) once the pressures are plausible.
* STOPPED_OVERHEAT: the brake is requested and the clutch torque ramps out over ``stop_release_s`` (a thermal
  monitor's stop too, from the pressure the last cycle's bound covered). Latched until
  the driver withdraws the creep request (then IDLE: still held).
* FAULT: plant frames missing or invalid: both clutches open, the brake requested, fault bit set; back to IDLE
  (held) when they return.

Every cycle the thermal monitor (:class:`ecu_stub.monitor.ThermalMonitor`) judges the pressures decided, in every
state: it limits a command whose plate bound would pass ``T_safe`` and turns a limit on the clutch that carries the
vehicle into STOPPED_OVERHEAT (:meth:`CreepController._supervised`; the argument: ``docs/safety.md``).

Start-up: a plate's temperature is unknown when the TCU wakes up, so it estimates it from the oil: the oil in a
clutch pack settles within a fraction of a second to the balance of heat from the plates and the cooling flow,
K (T_plate - T_oil_out) = cooling (T_oil_out - T_oil_in), so T_plate = T_oil_out + cooling / K (T_oil_out - T_oil_in),
with the sump temperature for T_oil_in (the oil is heated by the pump and valves on its way to the clutches, so
this over-estimates: the safe side). The TCU refuses to creep for ``startup_observer_s`` (five time constants of
the oil in the pack) while it takes its estimate from this observer; afterwards the predictor runs from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from dsg_hil.common.units import CV

from .calibration import TcuCalibration, load_calibration
from .clutch_model import heat_w, mu_lookup, nm_per_mpa, pressure_for_torque, slip_filter_weight
from .monitor import ThermalMonitor, crossover_heat_w, crossover_slip_rpm, release_time_s, worst_slip_rpm
from .pid import PID
from .plausibility import DISTANCE_M, HEAL_S, REL_TOL
from .sensor_checks import (GAIN_FLOOR_C, N_REL, OIL_FALL_K, P_ABS_MPA, P_REL, MatrixSteps, keyon_undetected_k,
                            oil_accuracy_at)

__all__ = ["BRAKE_PRESSED_PCT", "CreepController", "FAULT_PLANT_MISSING", "OTHER", "RUNAWAY_FRACTION", "STALL_FRACTION",
           "STALL_S", "TcuInputs", "TcuOutputs"]

OTHER = {"CL": "CH", "CH": "CL"}
FAULT_PLANT_MISSING = 0x01
CARRY_MARGIN = 0.1  # the on-coming clutch must give the wheel force with this fraction of its capacity to spare: the
# friction map's error at its highest pressures (carries; the sample's r00252: CH at 1.5 MPa gave 8 % less)
G_MPS2 = 9.81  # standard gravity as the vehicle data sheet has it [m/s^2] (the accelerometer's grade)
BRAKE_PRESSED_PCT = 5.0
CLUTCH_OPEN_MPA = 0.02  # measured piston pressure under which a clutch carries next to nothing (downhill check)
_RPM_TO_RAD_S = CV.RPM_TO_RAD_S
SETTLED_FRACTION = 0.05  # a creep within 5 % of its target (reference ramp done) has settled on the road load
STOOD_S = 0.5  # a creep whose vehicle stood this long, brakes off, stood on its force (_learn_standstill)
RUNAWAY_FRACTION = 0.2  # over the target by more than the drivability band (+-20 %), speeding up
STALL_FRACTION = 0.5  # stalled: under half the target speed with the wheel force at the clutch's capacity ...
STALL_S = 1.0  # ... for this long (10 time constants of the speed loop, 1/9.7 rad/s: not a transient)
SATURATED_FRACTION = 0.98  # the wheel force at its limit: within 2 % of the capacity (which moves with the slip)
# the shipped DBC's (CreepController takes the matrix's, of its MatrixSteps, as speed_q_mps, v_steady_step_mps,
# shaft_q_rpm):
SPEED_Q_MPS = 0.0005  # half a DBC step of VehicleSpeed [m/s] (margin_k: an output speed's error the vote lets through)
V_STEP_MPS = 0.0011  # a DBC step of VehicleSpeed [m/s], and a little more: a reading between two steps is steady
V_STEP_MORE = 1.1  # ... that little more: V_STEP_MPS is this many DBC steps of VehicleSpeed [1]
STEADY_S = 0.1  # VehicleSpeed steady this long under a brake: the vehicle stands (_track_stillness) [s]
V_UNDETECTED_MPS = DISTANCE_M / HEAL_S  # a steady VehicleSpeed offset the vote does not keep replaced [m/s]
SHAFT_Q_RPM = 0.1  # half a DBC step of a clutch output speed and of ClutchInputSpeed, 0.05 r/min each [r/min]
# (and OIL_FRAME_S of ecu_stub.sensor_checks, the oil frame's cycle time, as oil_frame_s)


@dataclass(slots=True)  # not frozen: built every control period, a frozen one costs several times more
class TcuInputs:
    plant_valid: bool
    engine_speed_rpm: float = 0.0
    clutch_in_rpm: float = 0.0
    cl_out_rpm: float = 0.0
    ch_out_rpm: float = 0.0
    v_mps: float = 0.0
    P_CL_mpa: float = 0.0
    P_CH_mpa: float = 0.0
    T_oil_CL_c: float = 25.0
    T_oil_CH_c: float = 25.0
    T_sump_c: float = 25.0
    creep_request: bool = False
    brake_pct: float = 0.0
    desired_speed_mps: float = 0.0
    fault_bits: int = 0  # protocol faults seen by the runner (CRC, counter, range)
    # False while a measured pressure is implausible (ecu_stub.sensor_checks: P_CL/P_CH then hold the larger of the
    # measured and the modelled pressure): a launch's brake is not released on a pressure nobody measured
    pressure_trusted: bool = True
    accel_mps2: float = 0.0  # PLANT_VEHICLE.LongAccel: the body's acceleration + g sin(grade) (prefill_force)
    # the largest oil step the settling check let through at start-up, per degC of its reading, by clutch
    # (ecu_stub.sensor_checks, OilCheck.undetected_ratio; margin_k)
    oil_step_ratio_CL: float = 0.0
    oil_step_ratio_CH: float = 0.0

    def __init__(self, plant_valid: bool, engine_speed_rpm: float = 0.0, clutch_in_rpm: float = 0.0,
                 cl_out_rpm: float = 0.0, ch_out_rpm: float = 0.0, v_mps: float = 0.0, P_CL_mpa: float = 0.0,
                 P_CH_mpa: float = 0.0, T_oil_CL_c: float = 25.0, T_oil_CH_c: float = 25.0, T_sump_c: float = 25.0,
                 creep_request: bool = False, brake_pct: float = 0.0, desired_speed_mps: float = 0.0,
                 fault_bits: int = 0, pressure_trusted: bool = True, accel_mps2: float = 0.0,
                 oil_step_ratio_CL: float = 0.0, oil_step_ratio_CH: float = 0.0) -> None:
        # the dataclass's own __init__ written out: built every control period, and setup.py's mypyc build compiles
        # a method written here but not one the dataclass generates (the fields and defaults above, the same)
        self.plant_valid, self.engine_speed_rpm, self.clutch_in_rpm = plant_valid, engine_speed_rpm, clutch_in_rpm
        self.cl_out_rpm, self.ch_out_rpm, self.v_mps = cl_out_rpm, ch_out_rpm, v_mps
        self.P_CL_mpa, self.P_CH_mpa = P_CL_mpa, P_CH_mpa
        self.T_oil_CL_c, self.T_oil_CH_c, self.T_sump_c = T_oil_CL_c, T_oil_CH_c, T_sump_c
        self.creep_request, self.brake_pct, self.desired_speed_mps = creep_request, brake_pct, desired_speed_mps
        self.fault_bits, self.pressure_trusted, self.accel_mps2 = fault_bits, pressure_trusted, accel_mps2
        self.oil_step_ratio_CL, self.oil_step_ratio_CH = oil_step_ratio_CL, oil_step_ratio_CH

    def slip_rpm(self, clutch: str) -> float:
        return self.clutch_in_rpm - (self.cl_out_rpm if clutch == "CL" else self.ch_out_rpm)

    def pressure_mpa(self, clutch: str) -> float:
        return self.P_CL_mpa if clutch == "CL" else self.P_CH_mpa

    def oil_c(self, clutch: str) -> float:
        return self.T_oil_CL_c if clutch == "CL" else self.T_oil_CH_c


@dataclass(slots=True)  # (as TcuInputs)
class TcuOutputs:
    P_CL_cmd_mpa: float
    P_CH_cmd_mpa: float
    state: str
    active_clutch: str  # "NONE", "CL" or "CH"
    brake_request: bool
    T_CL_pred_c: float
    T_CH_pred_c: float
    fault_bits: int
    decel_request_mps2: float = 0.0  # asked of the brakes (TCU_CMD.DecelRequest; CreepController.decel_request)

    def __init__(self, P_CL_cmd_mpa: float, P_CH_cmd_mpa: float, state: str, active_clutch: str, brake_request: bool,
                 T_CL_pred_c: float, T_CH_pred_c: float, fault_bits: int, decel_request_mps2: float = 0.0) -> None:
        # (written out as TcuInputs')
        self.P_CL_cmd_mpa, self.P_CH_cmd_mpa, self.state, self.active_clutch = (P_CL_cmd_mpa, P_CH_cmd_mpa, state,
                                                                                active_clutch)
        self.brake_request, self.T_CL_pred_c, self.T_CH_pred_c = brake_request, T_CL_pred_c, T_CH_pred_c
        self.fault_bits, self.decel_request_mps2 = fault_bits, decel_request_mps2


class CreepController:
    """The creep strategy (module docstring) with the calibration ``cal`` (None: the shipped one) on the matrix
    whose steps and times are ``steps`` (:meth:`ecu_stub.tcu_io.TcuIO.matrix_steps`; None: the shipped DBC's)."""

    def __init__(self, cal: TcuCalibration | None = None, steps: MatrixSteps | None = None) -> None:
        self.cal = cal or load_calibration()
        matrix = steps if steps is not None else MatrixSteps()
        self.steps = matrix
        # the matrix's steps and times (the shipped DBC's: SPEED_Q_MPS, V_STEP_MPS, SHAFT_Q_RPM, OIL_FRAME_S)
        self.speed_q_mps: float = 0.5 * matrix.v_step_mps  # half a step of VehicleSpeed [m/s]
        self.v_steady_step_mps: float = V_STEP_MORE * matrix.v_step_mps  # a step and a little more [m/s]
        # half a step of a clutch output speed and of ClutchInputSpeed [r/min]
        self.shaft_q_rpm: float = 0.5 * matrix.shaft_step_rpm + 0.5 * matrix.input_step_rpm
        self.oil_frame_s: float = matrix.oil_frame_s  # the oil frame's refresh [s]
        s = self.cal.speed
        # the wheel force's negative part goes to the brakes as a deceleration of the nominal mass (decel_request)
        self.pid = PID(s.kp_n_per_mps, s.ki_n_per_m, 0.0, -self.cal.vehicle.m_kg * s.decel_max_mps2, 1e9,
                       s.force_rate_n_per_s)
        self.state = "IDLE"
        self.active = "NONE"
        self.T_pred: dict[str, float] | None = None
        self.first_seen: float | None = None  # time of the first valid plant frames
        self.heat = {"CL": 0.0, "CH": 0.0}  # estimated friction power [W]
        self.P_cmd = {"CL": 0.0, "CH": 0.0}
        self.F_cmd = 0.0  # wheel force demanded by the speed controller [N]
        self.v_ref = 0.0  # speed reference: the desired speed reached along a ramp [m/s]
        self.brake_request = False
        self.held_untrusted = False  # the brake was requested because the clutches did not follow their commands
        self.last_now: float | None = None
        self.dt = 0.01  # the last control period [s]
        self.handover_from = "NONE"
        self.handover_t0 = 0.0
        self.near_limit_since: float | None = None
        self.stop_t0 = 0.0
        self.stop_P0 = {"CL": 0.0, "CH": 0.0}
        self.ramp_covered = "NONE"  # a monitor's stop: the clutch whose ramp out the last cycle's bound covered
        self.releasing = False  # IDLE, the clutches still ramping out over stop_release_s (_release_ramp)
        self.P_bounded = {"CL": 0.0, "CH": 0.0}  # the pressures the last cycle's bound was taken at [MPa]
        self.monitor = ThermalMonitor(self.cal)
        self.bound = {"CL": 0.0, "CH": 0.0}  # the monitor's bound of the last cycle [degC]
        self.inp = TcuInputs(plant_valid=False)  # the inputs of the last cycle
        self.F_creep = 0.0  # wheel force of the last creep settled on its target, or stood still [N] (prefill_force)
        self.creep_load = 0.0  # its load per unit weight: sin a + f cos a settled, sin a stood (prefill_force)
        self.sin_grade: float | None = None  # the grade's sine, read at the last held standstill (prefill_force)
        self.stood_since: float | None = None  # CREEP, VehicleSpeed 0 and no brake since (_learn_standstill)
        self.load_settled = False  # F_creep is a settled creep's, not a standstill's (_learn_standstill)
        self.slip_mean: dict[str, float] | None = None  # the clutches' slips low-passed [r/min] (mean_slip_rpm)
        self.stalled_since: float | None = None  # CREEP at the clutch's capacity under half the target (_stalled)
        self.pedal_overrun = False  # the driver's pedal pressed but not holding the vehicle (_idle)
        self.stand_held = False  # the vehicle stood held by the brake request since the last launch (_idle)
        self.still = False  # the vehicle stands, this cycle (_track_stillness)
        self.v_steady_mps = 0.0  # VehicleSpeed has stayed within a step of this since v_steady_since [m/s]
        self.v_steady_since = 0.0  # [s]
        self.heat_max = {"CL": 0.0, "CH": 0.0}  # the largest friction power since start-up, its error added [W]
        self.heat_error_k = {"CL": 0.0, "CH": 0.0}  # the prediction's error from undetected heat errors [K] (margin_k)
        self.oil_error_k: float | None = None  # an oil reading's undetected error, from the key-on readings (margin_k)
        self.oil_keyon_ratio = 0.0  # that error per degC of the key-on oil: a gain's (margin_k)
        self.oil_step_ratio = {"CL": 0.0, "CH": 0.0}  # the settling check's undetected step per degC (margin_k)
        self.oil_low_c = {"CL": math.inf, "CH": math.inf}  # the lowest oil reading after start-up [degC] (margin_k)

    def recalibrate(self, cal: TcuCalibration) -> None:
        """Run on with ``cal`` from the next cycle (a calibration value changed at run time, :mod:`ecu_stub.xcp`),
        keeping the state, the plate estimates and the integral: the speed controller's gains, limits and rate,
        and the thermal monitor, from the new values; everything else reads them each cycle."""
        self.cal = cal
        s, pid = cal.speed, self.pid
        pid.kp, pid.ki, pid.rate_limit = s.kp_n_per_mps, s.ki_n_per_m, s.force_rate_n_per_s
        pid.out_min = -cal.vehicle.m_kg * s.decel_max_mps2
        self.monitor = ThermalMonitor(cal)

    # ---- the clutch model ------------------------------------------------------------------------------------
    def observed_plate_c(self, clutch: str, inp: TcuInputs) -> float:
        """Plate temperature from the oil balance of the pack (start-up observer, see the module docstring)."""
        c, T_out = self.cal.clutch(clutch), inp.oil_c(clutch)
        return T_out + c.cooling_w_k / c.K_plate_oil_w_k * max(T_out - inp.T_sump_c, 0.0)

    @property
    def _T_pred(self) -> dict[str, float]:
        """The plate estimates [degC], known to be set (by the first :meth:`_predict`)."""
        assert self.T_pred is not None, "no plate estimate before the first valid plant frames"
        return self.T_pred

    def starting(self, now: float) -> bool:
        """True while the plate estimates still come from the start-up observer."""
        return self.first_seen is None or now - self.first_seen < self.cal.strategy.startup_observer_s

    def input_rpm(self, inp: TcuInputs) -> float:
        """The clutch input speed [r/min] of the thermal model (the prediction's heat, the monitor's and the handover
        limit's): the larger of ``ClutchInputSpeed`` and ``EngineSpeed`` / i_a (``vehicle.input_ratio``), the larger
        slip. The input speed check (:mod:`ecu_stub.sensor_checks`) lets ClutchInputSpeed read up to 40 r/min low,
        a third of a creep's heat; the engine's speed covers that (docs/safety.md)."""
        n_in, via_engine = inp.clutch_in_rpm, inp.engine_speed_rpm / self.cal.vehicle.input_ratio
        return n_in if n_in > via_engine else via_engine

    def _predict(self, inp: TcuInputs, dt: float, now: float, mean: dict[str, float]) -> None:
        """Advance both plate estimates, mu at the low-passed slips ``mean`` (:meth:`_filter_slip`, this cycle's
        included); at start-up, take them from the observer."""
        if self.first_seen is None:
            self.first_seen = now
            self.oil_error_k = self.keyon_oil_error_k(inp)
            hi = max(inp.T_oil_CL_c, inp.T_oil_CH_c, inp.T_sump_c)
            hi -= oil_accuracy_at(hi)  # the coldest the key-on oil may truly have been
            self.oil_keyon_ratio = self.oil_error_k / (hi if hi > GAIN_FLOOR_C else GAIN_FLOOR_C)
        ratio = self.oil_step_ratio
        if inp.oil_step_ratio_CL > ratio["CL"]:
            ratio["CL"] = inp.oil_step_ratio_CL
        if inp.oil_step_ratio_CH > ratio["CH"]:
            ratio["CH"] = inp.oil_step_ratio_CH
        if self.starting(now):
            self.T_pred = {c: self.observed_plate_c(c, inp) for c in ("CL", "CH")}
            return
        low = self.oil_low_c
        if inp.T_oil_CL_c < low["CL"]:
            low["CL"] = inp.T_oil_CL_c
        if inp.T_oil_CH_c < low["CH"]:
            low["CH"] = inp.T_oil_CH_c
        T_pred, heat, cal, clutch_in = self._T_pred, self.heat, self.cal, self.input_rpm(inp)
        heat_max, heat_error = self.heat_max, self.heat_error_k
        mu_of = mu_lookup(cal.friction)
        for c, clutch, out_rpm, P, T_oil in (("CL", cal.CL, inp.cl_out_rpm, inp.P_CL_mpa, inp.T_oil_CL_c),
                                             ("CH", cal.CH, inp.ch_out_rpm, inp.P_CH_mpa, inp.T_oil_CH_c)):
            # friction_heat(..., mu_slip_rpm=) and plate_step written out (the same operations): mu at the
            # low-passed slip, the heat at the measured one
            T, P, slip = T_pred[c], max(P, 0.0), abs(clutch_in - out_rpm)
            Q = heat[c] = heat_w(mu_of(T, abs(mean[c]), P), clutch, P, slip)
            dQ = self.heat_error_fraction(c, inp, P, slip) * Q  # the heat's undetected error (margin_k)
            if Q + dQ > heat_max[c]:
                heat_max[c] = Q + dQ
            K = clutch.K_plate_oil_w_k
            T_inf = T_oil + Q / K
            decay = math.exp(-K * dt / clutch.C_plate_j_k)
            T_pred[c] = T_inf + (T - T_inf) * decay
            e_inf = dQ / K  # the same model driven by the heat's undetected error (margin_k)
            heat_error[c] = e_inf + (heat_error[c] - e_inf) * decay

    def mean_slip_rpm(self, clutch: str, inp: TcuInputs) -> float:
        """|Slip| [r/min] of the clutch low-passed over ``SLIP_FILTER_S`` (:meth:`_filter_slip`), for the
        pressure of a torque (:meth:`pressure_for`, :meth:`force_at`); the present slip before the first valid
        cycle. Not the slip of the moment: on a hot pack at a fast idle (hot_1200 of bench/tcu_envelope.py) the output
        shafts rang by up to 220 r/min about the vehicle's speed, sampled every 10 ms into a slip jumping between 10
        and 400 r/min; mu looked up there moved the pressure by up to 30 % from one cycle to the next, which drove the
        ringing (a loop through the friction map's slip slope). Not the slip at the vehicle's speed either: a
        ``VehicleSpeed`` stuck at 0 would then set the pressure for the whole input speed as slip until the speed
        vote replaces it (0.1-0.2 s). The plate prediction (:meth:`_predict`) looks mu up at this slip too, the heat
        at the measured one: the heat of a ringing clutch is what it is, its friction follows the slip with a lag."""
        if self.slip_mean is None:
            return abs(inp.slip_rpm(clutch))
        return abs(self.slip_mean[clutch])

    def _filter_slip(self, inp: TcuInputs, dt: float) -> dict[str, float]:
        """Both clutches' slips [r/min] through a first-order low-pass of time constant ``SLIP_FILTER_S``
        (:func:`~ecu_stub.clutch_model.slip_filter_weight`; :attr:`slip_mean`, returned): the present slips on the
        first valid cycle."""
        CL, CH = inp.clutch_in_rpm - inp.cl_out_rpm, inp.clutch_in_rpm - inp.ch_out_rpm
        mean = self.slip_mean
        if mean is None:
            mean = self.slip_mean = {"CL": CL, "CH": CH}
            return mean
        a = slip_filter_weight(dt)
        mean["CL"] += a * (CL - mean["CL"])
        mean["CH"] += a * (CH - mean["CH"])
        return mean

    def pressure_for(self, clutch: str, force_n: float, inp: TcuInputs) -> float:
        """Piston pressure [MPa] for a wheel force: M = F * speed_ratio / eta, P = M / (mu(P) k_geom), mu looked up
        at the pressure it gives (:func:`~ecu_stub.clutch_model.pressure_for_torque`). Not at the measured pressure:
        while a clutch ramps out that lags above its command, and where mu rises with pressure (a hot plate under
        0.5 MPa) it took mu too high and the command too low, by 3-4 %, for the whole crossover (with the map's spike
        at 0.3 MPa, the 25-% dip of the 5,000-run sample's r00479)."""
        cal = self.cal
        c = cal.clutch(clutch)
        torque = max(force_n, 0.0) * c.speed_ratio_m / cal.vehicle.eta
        return min(pressure_for_torque(cal.friction, c, self._T_pred[clutch], self.mean_slip_rpm(clutch, inp), torque,
                                       self.P_cmd[clutch]), cal.speed.P_max_mpa)

    def force_at(self, clutch: str, P_mpa: float, inp: TcuInputs) -> float:
        """Wheel force [N] the clutch gives at the pressure P [MPa], mu looked up at P (:meth:`pressure_for`
        inverted)."""
        cal = self.cal
        c = cal.clutch(clutch)
        per_mpa = nm_per_mpa(mu_lookup(cal.friction)(self._T_pred[clutch], self.mean_slip_rpm(clutch, inp), P_mpa), c)
        return per_mpa * P_mpa * cal.vehicle.eta / c.speed_ratio_m

    def force_capacity(self, clutch: str, inp: TcuInputs) -> float:
        """Largest wheel force the clutch gives at the pressure limit [N]."""
        return self.force_at(clutch, self.cal.speed.P_max_mpa, inp)

    # ---- the thermal limits ----------------------------------------------------------------------------------
    def worst_heat(self, clutch: str) -> float:
        """Friction power [W] at the highest pressure the clutch may see (its command or the measured pressure) and
        the worst slip until it is released (:func:`ecu_stub.monitor.worst_heat_w`): the monitor's bound."""
        inp, cal = self.inp, self.cal  # worst_heat_w written out (the same operations: it runs every cycle)
        c, T = cal.clutch(clutch), self._T_pred[clutch]
        P, P_meas = self.P_cmd[clutch], inp.pressure_mpa(clutch)  # max() as comparisons: the same floats
        if P_meas > P:
            P = P_meas
        if P < 0.0:
            P = 0.0
        n_in = self.input_rpm(inp)
        slip, n_in = abs(n_in - (inp.cl_out_rpm if clutch == "CL" else inp.ch_out_rpm)), abs(n_in)
        slip = abs(n_in if n_in > slip else slip)
        return heat_w(mu_lookup(cal.friction)(T, slip, P), c, P, slip)

    def crossover_heat(self, clutch: str) -> float:
        """Friction power [W] the clutch would have through a crossover at its full share
        (:func:`ecu_stub.monitor.crossover_heat_w`): the monitor's pressure (command or measured, the larger), at the
        slip of the vehicle at its desired speed (or the present slip, if smaller)."""
        inp = self.inp
        P = max(self.P_cmd[clutch], inp.pressure_mpa(clutch), 0.0)
        n_in = self.input_rpm(inp)
        return crossover_heat_w(self.cal, clutch, self._T_pred[clutch], self.thermal_slip_rpm(clutch), n_in,
                                inp.desired_speed_mps, P)

    def crossover_rise_k(self, clutch: str, heat_w: float, worst_w: float | None = None) -> float:
        """Rise of an off-going plate after the decision [K], the larger of: the crossover at friction power
        ``heat_w`` at its full share (:meth:`crossover_heat`; its share falls linearly to zero over the handover,
        half of it on average; its pressure lags the command by the hydraulic lag; the decision may come one period
        late), and the monitor's fastest release at the worst power ``worst_w``
        (:func:`ecu_stub.monitor.release_time_s`; default ``heat_w``), so that at the decision the monitor's bound
        is within T_safe and it can always release the clutch in time if the crossover brings more heat. Cooling
        is neglected. With share 1 - t/t_h and power at most Q over the crossover,
        int_0^t_h (1 - t/t_h) Q dt = Q t_h / 2."""
        s, C = self.cal.strategy, self.cal.clutch(clutch).C_plate_j_k
        worst = heat_w if worst_w is None else worst_w
        return max(heat_w * (0.5 * s.handover_time_s + s.hydraulic_lag_s + self.dt),
                   worst * release_time_s(self.cal, self.dt)) / C

    def _track_stillness(self, inp: TcuInputs, now: float) -> None:
        """:attr:`still` for this cycle: the vehicle within the standstill band, or, braked (the brake requested in
        the last cycle, or the pedal pressed), VehicleSpeed steady within a DBC step for ``STEADY_S`` and within
        the band widened by what the speed vote lets through of a steady offset (:data:`V_UNDETECTED_MPS`): a
        braked vehicle that moves does not keep its speed, whatever offset its reading carries. Before, with
        VehicleSpeed reading 14.5 mm/s off (out-voted only after about 3 s), the TCU never saw the vehicle stand:
        its hold ended under a light pedal (8.2 m of roll-back of 11.76 t on 0.25 rad), the grade was never read
        and a launch's brake was released at once (110 mm/s back)."""
        v, standstill = inp.v_mps, self.cal.launch.standstill_mps
        if abs(v - self.v_steady_mps) > self.v_steady_step_mps:
            self.v_steady_mps, self.v_steady_since = v, now
        braked = self.brake_request or inp.brake_pct >= BRAKE_PRESSED_PCT
        self.still = abs(v) < standstill or (braked and abs(v) < standstill + V_UNDETECTED_MPS
                                             and now - self.v_steady_since >= STEADY_S - 1e-9)

    def slip_error_rpm(self, clutch: str, inp: TcuInputs) -> float:
        """Largest error [r/min] of the clutch's |slip| that the plausibility checks let through: its output speed
        within the speed vote's tolerance (:data:`~ecu_stub.plausibility.REL_TOL` of the vehicle speed and half DBC
        steps; an output speed beyond it is out-voted and replaced by the runner), the input speed within
        :data:`~ecu_stub.sensor_checks.N_REL` of itself (:meth:`input_rpm`: an input speed reading low is covered by
        the engine's) and half steps."""
        ratio = self.cal.clutch(clutch).speed_ratio_m * _RPM_TO_RAD_S
        return ((REL_TOL * abs(inp.v_mps) + self.speed_q_mps) / ratio
                + N_REL * abs(self.input_rpm(inp)) + self.shaft_q_rpm)

    def thermal_slip_rpm(self, clutch: str) -> float:
        """The clutch's slip [r/min] of the thermal model: :meth:`input_rpm` minus its output speed."""
        inp = self.inp
        return self.input_rpm(inp) - (inp.cl_out_rpm if clutch == "CL" else inp.ch_out_rpm)

    def heat_error_fraction(self, clutch: str, inp: TcuInputs, P_mpa: float, slip_rpm: float) -> float:
        """Largest relative error of a friction power mu k_geom P |slip| at pressure ``P_mpa`` and slip ``slip_rpm``
        that the plausibility checks let through: the pressure's :data:`~ecu_stub.sensor_checks.P_REL` +
        :data:`~ecu_stub.sensor_checks.P_ABS_MPA` / P and the slip's :meth:`slip_error_rpm` / |slip| (at most 1);
        0 at no pressure (no heat)."""
        if P_mpa <= 0.0:
            return 0.0
        dn, slip = self.slip_error_rpm(clutch, inp), abs(slip_rpm)
        return P_REL + P_ABS_MPA / P_mpa + dn / (slip if slip > dn else dn)

    def heat_scale(self, clutch: str) -> float:
        """Factor on the clutch's monitor and crossover powers for the undetected errors of their inputs:
        1 + :meth:`heat_error_fraction` at the larger of command and measured pressure (the monitor's) and the
        thermal slip."""
        inp = self.inp
        P = max(self.P_cmd[clutch], inp.pressure_mpa(clutch))
        return 1.0 + self.heat_error_fraction(clutch, inp, P, self.thermal_slip_rpm(clutch))

    def keyon_oil_error_k(self, inp: TcuInputs) -> float:
        """The most an oil reading may be low from key-on on and pass unflagged [K] (docs/safety.md): the
        key-on check's (:func:`~ecu_stub.sensor_checks.keyon_undetected_k` at the highest of the first cycle's
        oil temperatures; a substitute among them is higher, so the margin larger), but at least the sensor's
        accuracy at T_safe, ``strategy.oil_accuracy_k`` (a healthy sensor's error as the plate heats)."""
        hi = max(inp.T_oil_CL_c, inp.T_oil_CH_c, inp.T_sump_c)
        undetected, accuracy = keyon_undetected_k(hi), self.cal.strategy.oil_accuracy_k
        return undetected if undetected > accuracy else accuracy

    def margin_k(self, clutch: str) -> float:
        """The thermal margin's error term ``e`` of the clutch [K] (docs/safety.md): the predictor's
        identified error ``strategy.prediction_error_k``; an oil sensor's undetected error from key-on,
        :attr:`oil_error_k` (``strategy.oil_accuracy_k`` before the first cycle); the largest oil step the fall check
        lets through, :data:`~ecu_stub.sensor_checks.OIL_FALL_K` plus the plate's rise over one oil frame
        (:attr:`oil_frame_s`, the matrix's) at the largest heat since start-up (its undetected error
        added), in which a step hides; and :attr:`heat_error_k`, the prediction's own model driven by the heat's
        undetected error (:meth:`heat_error_fraction` x Q): C de/dt = dQ - K e, at most dQ / K."""
        return self.cal.strategy.prediction_error_k + self.oil_margin_k(clutch) + self.heat_error_k[clutch]

    def oil_margin_k(self, clutch: str) -> float:
        """The margin's term for the clutch's oil reading [K] (docs/safety.md): one fault on the sensor, an offset or
        a gain (a reading g T in degC, its error (1 - g) T growing with T), present at key-on or beginning later,
        the larger of the two.

        * At key-on: :attr:`oil_error_k`, or as a gain that error per degC of the key-on oil
          (:attr:`oil_keyon_ratio`) at ``T_safe``.
        * Later, on a sensor within its class (``strategy.oil_accuracy_k``): a step the fall check lets through,
          :data:`~ecu_stub.sensor_checks.OIL_FALL_K` plus the plate's rise over one oil frame (:attr:`oil_frame_s`)
          at the largest heat since start-up (its undetected error added), in which a step hides; as a gain, that
          step per degC of the lowest reading since start-up (:attr:`oil_low_c`) at ``T_safe``; or the step the
          settling check let through at start-up (:attr:`oil_step_ratio`), a gain at ``T_safe``."""
        s, c, oil = self.cal.strategy, self.cal.clutch(clutch), self.oil_error_k
        T_safe = s.T_safe_c
        keyon = s.oil_accuracy_k if oil is None else oil
        gain = self.oil_keyon_ratio * T_safe
        step = OIL_FALL_K + self.heat_max[clutch] / c.C_plate_j_k * self.oil_frame_s
        low = self.oil_low_c[clutch]
        ratio = step / (low if low > GAIN_FLOOR_C else GAIN_FLOOR_C) if low < math.inf else 0.0
        if self.oil_step_ratio[clutch] > ratio:
            ratio = self.oil_step_ratio[clutch]
        later = ratio * T_safe
        if step > later:
            later = step
        later += s.oil_accuracy_k
        if gain > keyon:
            keyon = gain
        return keyon if keyon > later else later

    def limit(self, clutch: str, heat_w: float | None = None, worst_w: float | None = None) -> float:
        """Predicted plate temperature at which the clutch must start handing over [degC]: T_safe - :meth:`margin_k`
        - :meth:`crossover_rise_k` x :meth:`heat_scale` (default: :meth:`crossover_heat` and :meth:`worst_heat`).
        Not the power of the decision instant: in a launch the clutch passes the launch's transient power (a vehicle
        still at rest slips the whole input speed), which the crossover, carried to the desired speed, does not
        see."""
        s = self.cal.strategy
        if heat_w is None:
            heat_w, worst_w = self.crossover_heat(clutch), self.worst_heat(clutch) if worst_w is None else worst_w
        return (s.T_safe_c - self.margin_k(clutch)
                - self.heat_scale(clutch) * self.crossover_rise_k(clutch, heat_w, worst_w))

    def takeover_heat(self, clutch: str) -> tuple[float, float]:
        """Friction powers [W] the clutch would have once it carries the vehicle, (4) as torque times slip: the
        torque for the wheel force it would take (the present demand; with none, the pre-fill a launch starts from:
        M = F * speed_ratio / eta, whatever mu), through a crossover (its slip at the desired speed,
        :func:`ecu_stub.monitor.crossover_slip_rpm`) and at the worst slip (:func:`ecu_stub.monitor.worst_slip_rpm`,
        the monitor's). Not the power of the clutch carrying now: the two clutches' gears differ (CH's torque for a
        wheel force is 1.73 times CL's, and it slips more at a creep speed), so the same wheel force heats CH about
        twice as fast as CL."""
        inp, cal = self.inp, self.cal
        force = self.F_cmd if self.F_cmd > 0.0 else self.prefill_force()
        torque_rad = force * cal.clutch(clutch).speed_ratio_m / cal.vehicle.eta * _RPM_TO_RAD_S
        slip, clutch_in = self.thermal_slip_rpm(clutch), self.input_rpm(inp)
        return (torque_rad * crossover_slip_rpm(cal, clutch, slip, clutch_in, inp.desired_speed_mps),
                torque_rad * worst_slip_rpm(slip, clutch_in))

    def can_take_over(self, clutch: str) -> bool:
        """The clutch may take the load if its estimate is ``takeover_headroom_k`` under its limit, the limit taken at
        the larger friction powers of the two clutches now (the on-coming clutch will carry the same wheel force) and
        of the clutch once it carries (:meth:`takeover_heat`)."""
        load, worst = self.takeover_heat(clutch)
        load = max(load, *self.heat.values())
        worst = max(worst, self.worst_heat("CL"), self.worst_heat("CH"))
        return self._T_pred[clutch] <= self.limit(clutch, load, worst) - self.cal.strategy.takeover_headroom_k

    def carries(self, clutch: str, inp: TcuInputs) -> bool:
        """Whether the clutch can give the wheel force demanded now (:meth:`force_capacity` at its present slip) with
        :data:`CARRY_MARGIN` to spare. Found by the 5,000-run sample on e407739 (10 of 46 runs of vehicles over 9 t on
        grades over 0.15 rad without a frame fault left +-20 % through a handover): r00252, 11.0 t on 0.22 rad, was
        handed over to CH with the force 0.2 % under CH's modelled capacity; at 1.5 MPa CH gave 8 % less than the
        map says, and the vehicle slowed from 0.28 to 0.01 m/s before the stall rule stopped it. With no partner
        that carries, the active clutch carries on to the monitor's stop (:meth:`update`)."""
        return (1.0 - CARRY_MARGIN) * self.force_capacity(clutch, inp) >= self.F_cmd

    def _stalled(self, inp: TcuInputs, now: float) -> bool:
        """(Called in CREEP, every cycle; a launch, ENGAGE, starts it afresh.) The wheel force at the active clutch's
        capacity (the speed controller's limit) and the vehicle under ``1 - STALL_FRACTION`` of its target, for
        ``STALL_S``: the clutch cannot carry the vehicle (CH's gear needs 1.73 times CL's torque for a wheel force: a
        heavy vehicle on a steep grade is beyond CH at its pressure limit). Found by the 5,000-run sample: 11.0 t on
        0.175 rad at 1,486 r/min, CL at its limit after 13 s of creep, handed over to CH, which at 1.5 MPa slowed the
        vehicle to 9 mm/s and held it there while creep was requested (CH heating at 7.5 K/s)."""
        stalled = (self.F_cmd >= SATURATED_FRACTION * self.pid.out_max
                   and inp.v_mps < (1.0 - STALL_FRACTION) * inp.desired_speed_mps)
        if not stalled:
            self.stalled_since = None
            return False
        if self.stalled_since is None:
            self.stalled_since = now
        return now - self.stalled_since >= STALL_S

    def _limit_reached(self, now: float) -> bool:
        c = self.active
        limit = self.limit(c)
        if self._T_pred[c] >= limit:
            return True
        if self._T_pred[c] >= limit - self.cal.strategy.dwell_band_k:
            if self.near_limit_since is None:
                self.near_limit_since = now
            return now - self.near_limit_since >= self.cal.strategy.dwell_time_s
        self.near_limit_since = None
        return False

    # ---- the strategy ------------------------------------------------------------------------------------------
    def update(self, inp: TcuInputs, now: float) -> TcuOutputs:
        dt = 0.01 if self.last_now is None else now - self.last_now
        if self.last_now is not None and not dt > 0.0:
            raise ValueError(f"time must advance: {now} after {self.last_now}")
        self.last_now, self.dt = now, dt
        faults = inp.fault_bits
        if not inp.plant_valid:  # the vehicle is held by the brake until the plant's frames return
            self.slip_mean = None  # (filtered again from the first frames back)
            if self.state != "FAULT":
                self.state, self.active, self.brake_request = "FAULT", "NONE", True
                self._open_both()
            return self._outputs(faults | FAULT_PLANT_MISSING)
        self._predict(inp, dt, now, self._filter_slip(inp, dt))
        last, self.inp = self.inp, inp
        if self.state == "FAULT":
            self.state = "IDLE"
        self._track_stillness(inp, now)
        self._read_grade(inp)

        if self.state == "STOPPED_OVERHEAT":
            if not inp.creep_request:  # IDLE, still held (_idle): the next TCU_STATUS may be the plant's for 100 ms
                self.releasing = True  # (the stop's ramp goes on)
                self._idle(inp, last, inp.brake_pct >= BRAKE_PRESSED_PCT, now)
            else:
                self._release_ramp(now)
            return self._supervised(inp, now, faults)

        pedal = inp.brake_pct >= BRAKE_PRESSED_PCT
        # desired speed 0 with creep requested: stand, held by the brake request (_idle), not a creep at 0 (the
        # clutch alone let 11.76 t on 0.25 rad roll back at 17 mm/s); a creep asked to 0 first slows to a standstill
        stand = inp.desired_speed_mps <= 0.0 and (self.state == "IDLE" or (
            self.v_ref <= 0.0 and self.still))
        if not (inp.creep_request and not pedal) or self.starting(now) or stand:
            if self.state in ("ENGAGE", "CREEP", "HANDOVER") and not pedal:
                # the creep request withdrawn without the brake: the brake request reaches the brakes with the next
                # TCU_STATUS (up to 100 ms); the clutches ramp out meanwhile, as at a stop, instead of dropping the
                # vehicle (the 5,000-run sample: up to 15 mm/s of roll-back on 0.2-0.24 rad)
                self.releasing, self.stop_t0, self.stop_P0 = True, now, dict(self.P_cmd)
            self._idle(inp, last, pedal, now)
            return self._supervised(inp, now, faults) if self.releasing else self._outputs(faults)

        if self.state == "IDLE":
            first = "CL" if self.can_take_over("CL") else "CH"
            if not self.can_take_over(first):
                return self._stop(now, faults)
            self._engage(first)
            self.brake_request = self.brake_request and self.still

        if self.state in ("CREEP", "HANDOVER"):
            self._hold_speed(inp, last)
        step = self.cal.launch.accel_mps2 * dt
        self.v_ref = min(max(inp.desired_speed_mps, self.v_ref - step), self.v_ref + step)
        v_err = self.v_ref - inp.v_mps
        if self.state == "ENGAGE":
            P = self.P_cmd[self.active] = self.pressure_for(self.active, self.F_cmd, inp)
            if inp.pressure_trusted and inp.pressure_mpa(self.active) >= self.cal.launch.prefill_ready_fraction * P:
                self.state, self.brake_request = "CREEP", False
                self.pid.reset(self._creep_start_force())
                self.v_ref = max(inp.v_mps, 0.0)
        elif self.state == "CREEP":
            self.F_cmd = self._speed_control(v_err, dt, self.active, inp)
            if (not self.brake_request and self.v_ref == inp.desired_speed_mps > 0.0
                    and abs(v_err) <= SETTLED_FRACTION * inp.desired_speed_mps):
                self._learn_road_load()
            self._learn_standstill(inp, now)
            self.P_cmd[self.active] = self.pressure_for(self.active, self.F_cmd, inp)
            self.P_cmd[OTHER[self.active]] = 0.0
        elif self.state == "HANDOVER":
            x = min((now - self.handover_t0) / self.cal.strategy.handover_time_s, 1.0)
            self.F_cmd = self._speed_control(v_err, dt, self.active, inp, share=x)
            self.P_cmd[self.active] = self.pressure_for(self.active, x * self.F_cmd, inp)
            self.P_cmd[self.handover_from] = 0.0 if x >= 1.0 else \
                self.pressure_for(self.handover_from, (1.0 - x) * self.F_cmd, inp)
            if x >= 1.0:
                self.state = "CREEP"

        stalled = self.state == "CREEP" and self._stalled(inp, now)
        if self.state in ("CREEP", "ENGAGE") and (stalled or self._limit_reached(now)):
            other = OTHER[self.active]
            if not self.can_take_over(other):
                return self._stop(now, faults)
            if not self.carries(other, inp):
                if stalled:  # neither clutch can carry the vehicle
                    return self._stop(now, faults)
                # the other clutch could not carry the vehicle: this one carries on, up to the monitor's stop
                return self._supervised(inp, now, faults)
            if self.state == "ENGAGE":  # hold the pre-fill on the other clutch, as a fresh engage
                self.P_cmd[self.active], self.active = 0.0, other
                self.near_limit_since = None
                return self._supervised(inp, now, faults)
            self.state, self.handover_from, self.active = "HANDOVER", self.active, other
            self.handover_t0 = now
            self.near_limit_since = self.stalled_since = None
        return self._supervised(inp, now, faults)

    def _supervised(self, inp: TcuInputs, now: float, faults: int) -> TcuOutputs:
        """The outputs after the thermal monitor (:mod:`ecu_stub.monitor`): pressures limited where its bound
        would pass T_safe, and a stop if the clutch that carries the vehicle had to be limited."""
        carrying = "NONE" if self.state == "STOPPED_OVERHEAT" else self.active
        clutch_in = self.input_rpm(inp)  # (thermal_slip_rpm and pressure_mpa of each clutch, written out)
        P_meas = {"CL": inp.P_CL_mpa, "CH": inp.P_CH_mpa}
        slips = {"CL": clutch_in - inp.cl_out_rpm, "CH": clutch_in - inp.ch_out_rpm}
        error_k = {"CL": self.margin_k("CL"), "CH": self.margin_k("CH")}
        scale = {"CL": self.heat_scale("CL"), "CH": self.heat_scale("CH")}
        verdict = self.monitor.check(self._T_pred, slips, clutch_in, self.P_cmd, P_meas, carrying, self.dt, error_k,
                                     scale)
        off = self.handover_from
        if self.state == "HANDOVER" and off in verdict.P_limit_mpa and not verdict.stop:
            # the off-going clutch released faster than its share: the on-coming one takes the rest of the wheel
            # force (judged again), not the speed controller's integral (the dip and overshoot it made: a heavy
            # launch's handover on 0.211 rad dipped to 0.193 m/s and overshot to 0.436 m/s against 0.3055)
            P_off = min(self.P_cmd[off], verdict.P_limit_mpa[off])
            rest = self.F_cmd - self.force_at(off, P_off, inp)
            self.P_cmd[off] = P_off
            self.P_cmd[carrying] = max(self.P_cmd[carrying], self.pressure_for(carrying, rest, inp))
            verdict = self.monitor.check(self._T_pred, slips, clutch_in, self.P_cmd, P_meas, carrying, self.dt,
                                         error_k, scale)
        covered = self.ramp_covered if self.state == "STOPPED_OVERHEAT" else "NONE"
        proposed = self.P_cmd[carrying] if carrying != "NONE" else 0.0
        for c, P in verdict.P_limit_mpa.items():
            if c != covered:
                self.P_cmd[c] = min(self.P_cmd[c], P)
        last_bound, last_P = self.bound, self.P_bounded
        self.bound = verdict.bound_c
        self.P_bounded = {c: max(self.P_cmd[c], P_meas[c]) for c in ("CL", "CH")}
        if verdict.stop and self.state != "STOPPED_OVERHEAT":
            self._stop(now, faults)
            if last_bound[carrying] <= self.cal.strategy.T_safe_c:
                # the last cycle's bound covered a ramp out starting now from the pressure it was taken at (the
                # monitor's release time: one period, the lag, half the ramp): the clutch ramps out from there,
                # not from the limit (zero once even the measured pressure passes the bound), which would drop
                # the vehicle until the brake request reaches the brakes (the 5,000-run sample: 11.8 mm/s back)
                self.P_cmd[carrying] = self.stop_P0[carrying] = min(proposed, last_P[carrying])
                self.ramp_covered = carrying
        return self._outputs(faults)

    def _hold_speed(self, inp: TcuInputs, last: TcuInputs) -> None:
        """Downhill: at creep speeds both clutches slip forwards and cannot brake; the speed controller asks the
        brakes for a deceleration (:meth:`decel_request`). Should the vehicle still be more than
        ``speed.overspeed_fraction`` over its target and speeding up with that request at its limit and both
        clutches open (brakes that do not follow the request), the TCU requests the full brake (speed controller
        held at zero force) until the vehicle stands: long enough for the request to reach the brakes (TCU_STATUS),
        which stop it at once (one bit: the full service brake).

        The clutches not following their commands (a measured pressure implausible against the command,
        ``inp.pressure_trusted`` False: a valve that builds no pressure, or the TCU's commands lost on the bus, after
        which the gearbox releases both clutches) with the vehicle standing, rolling back or over its target:
        nothing carries the vehicle, so the TCU requests the brake and holds it while the pressures stay
        implausible. Once they are plausible again it launches as from rest (ENGAGE: the pre-fill under the brake,
        released when the measured pressure has built up), not on the check's healing alone: with the commands
        still lost the check heals once the command and the released pressure agree, and releasing the brake then
        rolled the vehicle back again (0.117 m for 5 s of frozen counters on a 0.243-rad grade, now 0.014 m).
        Over its target means here beyond the drivability band (:data:`RUNAWAY_FRACTION`) and still speeding up: a
        launch's overshoot (+7 % on Table I's grade) is not a runaway. A sensor reading wrong on a clutch that
        works moves the vehicle as commanded: no brake against the clutch."""
        # speeding up with both clutches open (commanded and measured): the slope pushes, not a lagging piston
        # (and the brakes' deceleration at its limit: they do not hold it)
        pushed = (inp.v_mps > last.v_mps and self.F_cmd <= self.pid.out_min
                  and max(inp.P_CL_mpa, inp.P_CH_mpa) < CLUTCH_OPEN_MPA)
        braking = self.brake_request
        over = inp.v_mps > inp.desired_speed_mps * (1.0 + self.cal.speed.overspeed_fraction)
        standstill = self.cal.launch.standstill_mps
        if over and pushed:
            self.brake_request = True
        elif not inp.pressure_trusted and (inp.v_mps < standstill or (
                inp.v_mps > inp.desired_speed_mps * (1.0 + RUNAWAY_FRACTION) and inp.v_mps > last.v_mps)):
            self.brake_request = self.held_untrusted = True  # the clutches do not carry it: it rolls, or is pushed
        elif braking and self.still and inp.pressure_trusted:
            if self.held_untrusted:  # launch again: the brake holds until the measured pressure has built up
                self.held_untrusted = False
                self.P_cmd[OTHER[self.active]] = 0.0
                self._engage(self.active)
                return
            self.brake_request = False
        if braking or self.brake_request:  # the speed controller starts again from zero force at this speed
            self.pid.reset(0.0)
            self.v_ref = max(inp.v_mps, 0.0)

    def _speed_control(self, v_err: float, dt: float, clutch: str, inp: TcuInputs, share: float = 1.0) -> float:
        """PI on speed with a wheel-force output limited to what the clutches can give (anti-windup), its integral
        held while the measured pressures are implausible (``inp.pressure_trusted`` False: the clutches do not follow
        the commands, e.g. the commands are lost on the bus), so that it does not wind up against a vehicle nothing
        drives and overshoot once the commands reach the clutches again."""
        cap = self.force_capacity(clutch, inp)
        if share < 1.0:
            cap = min(cap / max(share, 1e-3), self.force_capacity(self.handover_from, inp) / max(1.0 - share, 1e-3))
        self.pid.out_max = cap
        if inp.pressure_trusted:
            return self.pid.update(v_err, dt)
        held = self.pid.integral  # the clutches do not follow their commands: integrating would wind up
        out = self.pid.update(v_err, dt)
        self.pid.integral = min(held, cap)
        return out

    def _engage(self, clutch: str) -> None:
        """A launch on ``clutch``: ENGAGE, the pre-fill's force (:meth:`prefill_force`), no dwell running; a pedal
        overrun ends with it (the pedal it overruled is off)."""
        self.state, self.active, self.near_limit_since, self.stalled_since = "ENGAGE", clutch, None, None
        self.pedal_overrun, self.stand_held, self.stood_since = False, False, None
        self.F_cmd = self.prefill_force()

    def _read_grade(self, inp: TcuInputs) -> None:
        """The grade's sine from the accelerometer (``LongAccel``: dv/dt + g sin a) while the vehicle stands held
        (VehicleSpeed 0, or :attr:`still`: within the standstill band or steady, the brake requested or pressed:
        dv/dt about 0; read anew every such cycle, so the last before a launch is the held vehicle's), within
        ``launch.grade_max_rad`` (a faulty reading cannot ask for more than the steepest grade's pre-fill)."""
        if (inp.v_mps == 0.0 or self.still) and (self.brake_request or inp.brake_pct >= BRAKE_PRESSED_PCT):
            s_max = math.sin(self.cal.launch.grade_max_rad)
            self.sin_grade = min(max(inp.accel_mps2 / G_MPS2, -s_max), s_max)

    def _learn_road_load(self) -> None:
        """A creep settled on its target: its wheel force is the road load m g (sin a + f cos a) of this vehicle on
        this grade (the force as the TCU's clutch model has it, so the pre-fill it gives is what this vehicle needs
        through the same model). Learned only on a grade read at a standstill."""
        if self.sin_grade is not None:
            self.F_creep, self.creep_load = self.F_cmd, self._load_per_weight(self.sin_grade)
            self.load_settled = True

    def _learn_standstill(self, inp: TcuInputs, now: float) -> None:
        """A creep whose vehicle stood still for ``STOOD_S`` with no brake on (requested or pressed) and nothing
        learned from a settled creep, the force under the clutch's capacity (at it, the commanded force is not the
        transmitted one: :meth:`_stalled`): its wheel force held this vehicle, so it lies within the window
        m g (sin a +- f0 cos a) where a standing vehicle stays, the middle of which is m g sin a: the weight the
        pre-fill needs (:meth:`prefill_force`), learned as a load per weight of sin a. A creep that never settles
        (the monitor stops the clutch before the vehicle reaches its target) otherwise leaves every later launch
        on the heaviest vehicle's pre-fill. Found by the safety proof sweep (r00408: 10.8 t on 0.279 rad, beyond
        the 0.25 rad the grade is read up to, stop-and-go at 0.0255 m/s): each of 7 launches rolled back
        12-15 mm, 0.080 m in all (limit 0.05 m); now the first only, 12 mm."""
        if self.load_settled or self.sin_grade is None or inp.v_mps != 0.0 or self.brake_request \
                or inp.brake_pct > 0.0 or self.F_cmd >= SATURATED_FRACTION * self.pid.out_max:
            self.stood_since = None
            return
        if self.stood_since is None:
            self.stood_since = now
        elif now - self.stood_since >= STOOD_S:
            self.F_creep, self.creep_load = self.F_cmd, self.sin_grade

    def _load_per_weight(self, s: float) -> float:
        """Road load per unit weight on a grade of sine ``s``, sin a + f cos a (f: ``vehicle.f_roll``)."""
        return s + self.cal.vehicle.f_roll * math.sqrt(1.0 - s * s)

    def prefill_force(self) -> float:
        """Wheel force [N] of a launch's pre-fill, for the grade a read at the last standstill (:meth:`_read_grade`).
        A standing vehicle stays where it is between m g (sin a - f0 cos a) and m g (sin a + f0 cos a) (f0 the
        small breakaway resistance), and a rolling one speeds up backwards only below m g (sin a - f cos a) (f the
        rolling resistance of (13)). Nothing learned, the mass is unknown: the heaviest vehicle's
        ``vehicle.m_max_kg`` g (sin a - f cos a), so that no vehicle rolls back faster and faster (a lighter one is
        held better: up to tan a = 2 f with a mass range of +-50 %, it is not pushed beyond its own road load).
        After a creep settled on its target (:meth:`_learn_road_load`) or stood still under its force
        (:meth:`_learn_standstill`) the weight is known: m g sin a, the middle of the window where a standing
        vehicle stays. Never below ``launch.F_prefill_n``, the pre-fill of a gentle or
        unknown grade. Measured (the 5,000-run sample's r02259: 9.4 t on 0.236 rad, creep toggled with the brake
        every 2.8 s at 0.055 m/s, never settled): the fixed pre-fill let it roll back about 3 mm at up to 28 mm/s at
        every launch, 0.132 m in all."""
        launch, f = self.cal.launch, self.cal.vehicle.f_roll
        s = 0.0 if self.sin_grade is None else self.sin_grade
        if self.F_creep > 0.0 and self.creep_load >= 0.5 * f:  # (downhill the creep force says little of m)
            force = self.F_creep / self.creep_load * s
        else:
            c = math.sqrt(1.0 - s * s)
            force = min(self.cal.vehicle.m_max_kg * G_MPS2 * (s - f * c),
                        launch.push_fraction * self.cal.vehicle.m_min_kg * G_MPS2 * (s + f * c))
        return max(launch.F_prefill_n, force)

    def _creep_start_force(self) -> float:
        """Wheel force [N] the speed controller starts a creep from once the pre-fill carries: the pre-fill's, but
        downhill, where the grade read at the standstill pushes the vehicle harder than it rolls
        (sin a + f cos a < 0), the nominal vehicle's road load ``vehicle.m_kg`` g (sin a + f cos a), a braking force
        (:meth:`decel_request`): started from the pre-fill, the integral took over a second to unwind and the launch
        overshot (-0.15 rad, 0.206 m/s asked: 0.251 m/s, +22 %)."""
        if self.sin_grade is not None and (load := self._load_per_weight(self.sin_grade)) < 0.0:
            return self.cal.vehicle.m_kg * G_MPS2 * load
        return self.F_cmd

    def _idle(self, inp: TcuInputs, last: TcuInputs, pedal: bool, now: float) -> None:
        """No creep wanted (or not yet allowed): clutches open (ramping out over ``stop_release_s`` if
        :attr:`releasing`), and the vehicle held by the brake request unless the driver brakes a moving vehicle
        himself, and his pedal does hold it. A vehicle that stood held stays held until the next launch, pedal or
        not (:attr:`stand_held`: a VehicleSpeed reading off by more than the standstill band, within what the
        speed vote lets through, must not end the hold; before, -14.5 mm/s let 11.76 t on 0.25 rad roll back 8.2 m
        under a 6.3 % pedal). A pedal counted as pressed (``BRAKE_PRESSED_PCT``) but too light for the slope is
        overruled, the brake requested until the vehicle stands (:attr:`pedal_overrun`): forwards, over its target
        by more than the drivability band (:data:`RUNAWAY_FRACTION`; over a standstill if none is asked) and
        speeding up (without it, 6 % on -0.30 rad ran away to 8.5 m/s); backwards, beyond the standstill band and
        speeding up (no creep asks to roll back)."""
        self.state, self.active = "IDLE", "NONE"
        self._open_both()
        if self.releasing:
            self.releasing = self._release_ramp(now)
        self.held_untrusted = False
        standstill = self.cal.launch.standstill_mps
        v, v_last, standing = inp.v_mps, last.v_mps, self.still
        target = max(inp.desired_speed_mps, 0.0) * (1.0 + RUNAWAY_FRACTION) if inp.creep_request else 0.0
        if standing or not pedal:
            self.pedal_overrun = False
        elif (v > target + standstill and v > v_last) or (v < -standstill and v < v_last):
            self.pedal_overrun = True
        self.stand_held = self.stand_held or standing
        self.brake_request = standing or not pedal or self.pedal_overrun or self.stand_held

    def _open_both(self) -> None:
        self.P_cmd = {"CL": 0.0, "CH": 0.0}
        self.F_cmd = 0.0
        self.pid.reset(0.0)

    def _release_ramp(self, now: float) -> bool:
        """The clutches' commands on the ramp out from ``stop_P0`` over ``stop_release_s`` since ``stop_t0`` (while
        the brake request reaches the brakes); False once it has ended."""
        release_s = self.cal.strategy.stop_release_s
        x = 1.0 if release_s <= 0 else min((now - self.stop_t0) / release_s, 1.0)
        self.P_cmd = {c: P * (1.0 - x) for c, P in self.stop_P0.items()}
        return x < 1.0

    def _stop(self, now: float, faults: int) -> TcuOutputs:
        self.state, self.active, self.brake_request = "STOPPED_OVERHEAT", "NONE", True
        self.stop_t0, self.stop_P0, self.ramp_covered, self.releasing = now, dict(self.P_cmd), "NONE", False
        self.F_cmd = 0.0
        return self._outputs(faults)

    def decel_request(self) -> float:
        """Deceleration [m/s^2] asked of the brakes (TCU_CMD.DecelRequest): in CREEP and HANDOVER, the negative part
        of the speed controller's wheel force over the nominal mass ``vehicle.m_kg`` (its integral makes up for
        another mass), at most ``speed.decel_max_mps2``; none while the full brake is requested."""
        if self.F_cmd >= 0.0 or self.brake_request or self.state not in ("CREEP", "HANDOVER"):
            return 0.0
        return min(-self.F_cmd / self.cal.vehicle.m_kg, self.cal.speed.decel_max_mps2)

    def _outputs(self, faults: int) -> TcuOutputs:
        T = self.T_pred or {"CL": 0.0, "CH": 0.0}
        return TcuOutputs(self.P_cmd["CL"], self.P_cmd["CH"], self.state, self.active, self.brake_request,
                          T["CL"], T["CH"], faults, self.decel_request())
