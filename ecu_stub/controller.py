"""The creep strategy of the paper (Fig. 7, Section V) as ``CreepController.update(inputs, now) -> outputs``.

No bus, no clock: time is passed in, so the strategy is tested with a fake clock and can run behind any bus.

* IDLE: both clutches open. Hill-hold: while the vehicle stands and the driver brakes, the TCU also requests the
  brake, so the vehicle stays held when the driver's foot comes off (released after ``launch.hold_max_s`` if the
  driver does not ask to creep).
* ENGAGE: on the creep request, the on-coming clutch (CL first) is filled at once to the pressure that carries
  ``launch.F_prefill_n`` at the wheel (enough to hold the heaviest vehicle on the steepest documented grade, with
  rolling resistance); the brake request is dropped when the measured pressure has reached it.
* CREEP: a PI controller on vehicle speed sets the wheel force (its reference reaches the desired speed along a
  ramp of ``launch.accel_mps2``, so a launch or a new desired speed is no step); the active clutch's pressure
  follows from the TCU's model of that clutch (torque = mu(T, slip, P) k_geom P, the speed ratio to the wheel,
  efficiency).
* HANDOVER: a torque handover as in a DCT shift: over ``handover_time_s`` the on-coming clutch takes a growing
  share x of the wheel force and the off-going the rest (1 - x), each converted to pressure by its own model,
  while the speed controller keeps running.
* The handover starts when the active clutch's *predicted* plate temperature reaches its limit
  ``T_safe - prediction_error_k - dT_crossover`` (``dT_crossover``: the heat still coming into the off-going plate
  while its share ramps out and its pressure lags, from its present friction power; see :meth:`limit`), or when
  the prediction has stayed within ``dwell_band_k`` under the limit for ``dwell_time_s``. The other clutch takes
  over if it is predicted ``takeover_headroom_k`` under its limit; otherwise STOPPED_OVERHEAT.
* STOPPED_OVERHEAT: the brake is requested and the clutch torque ramps out over ``stop_release_s``. Latched until
  the driver withdraws the creep request.
* FAULT: plant frames missing or invalid: both clutches open, fault bit set; back to IDLE when they return.

Start-up: a plate's temperature is unknown when the TCU wakes up, so it estimates it from the oil: the oil in a
clutch pack settles within a fraction of a second to the balance of heat from the plates and the cooling flow,
K (T_plate - T_oil_out) = cooling (T_oil_out - T_oil_in), so T_plate = T_oil_out + cooling / K (T_oil_out - T_oil_in),
with the sump temperature for T_oil_in (the oil is heated by the pump and valves on its way to the clutches, so
this over-estimates: the safe side). The TCU refuses to creep for ``startup_observer_s`` (five time constants of
the oil in the pack) while it takes its estimate from this observer; afterwards the predictor runs from it.
"""

from __future__ import annotations

from dataclasses import dataclass

from .calibration import TcuCalibration, load_calibration
from .clutch_model import friction_heat, plate_step, torque_per_mpa
from .pid import PID

__all__ = ["BRAKE_PRESSED_PCT", "CreepController", "FAULT_PLANT_MISSING", "OTHER", "TcuInputs", "TcuOutputs"]

OTHER = {"CL": "CH", "CH": "CL"}
FAULT_PLANT_MISSING = 0x01
BRAKE_PRESSED_PCT = 5.0


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


class CreepController:
    def __init__(self, cal: TcuCalibration | None = None) -> None:
        self.cal = cal or load_calibration()
        s = self.cal.speed
        self.pid = PID(s.kp_n_per_mps, s.ki_n_per_m, 0.0, 0.0, 1e9, s.force_rate_n_per_s)
        self.state = "IDLE"
        self.active = "NONE"
        self.T_pred: dict[str, float] | None = None
        self.first_seen: float | None = None  # time of the first valid plant frames
        self.heat = {"CL": 0.0, "CH": 0.0}  # estimated friction power [W]
        self.P_cmd = {"CL": 0.0, "CH": 0.0}
        self.F_cmd = 0.0  # wheel force demanded by the speed controller [N]
        self.v_ref = 0.0  # speed reference: the desired speed reached along a ramp [m/s]
        self.brake_request = False
        self.hold_since: float | None = None  # hill-hold: when the driver's foot came off without a creep request
        self.last_now: float | None = None
        self.dt = 0.01  # the last control period [s]
        self.handover_from = "NONE"
        self.handover_t0 = 0.0
        self.near_limit_since: float | None = None
        self.stop_t0 = 0.0
        self.stop_P0 = {"CL": 0.0, "CH": 0.0}

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

    def _predict(self, inp: TcuInputs, dt: float, now: float) -> None:
        """Advance both plate estimates; at start-up, take them from the observer."""
        if self.first_seen is None:
            self.first_seen = now
        if self.starting(now):
            self.T_pred = {c: self.observed_plate_c(c, inp) for c in ("CL", "CH")}
            return
        T_pred, heat, cal, clutch_in = self._T_pred, self.heat, self.cal, inp.clutch_in_rpm
        for c, clutch, out_rpm, P, T_oil in (("CL", cal.CL, inp.cl_out_rpm, inp.P_CL_mpa, inp.T_oil_CL_c),
                                             ("CH", cal.CH, inp.ch_out_rpm, inp.P_CH_mpa, inp.T_oil_CH_c)):
            heat[c] = friction_heat(cal.friction, clutch, T_pred[c], clutch_in - out_rpm, P)  # slip as slip_rpm(c)
            T_pred[c] = plate_step(clutch, T_pred[c], heat[c], T_oil, dt)

    def pressure_for(self, clutch: str, force_n: float, inp: TcuInputs) -> float:
        """Piston pressure [MPa] for a wheel force: M = F * speed_ratio / eta, P = M / (mu k_geom)."""
        c = self.cal.clutch(clutch)
        torque = max(force_n, 0.0) * c.speed_ratio_m / self.cal.vehicle.eta
        per_mpa = torque_per_mpa(self.cal.friction, c, self._T_pred[clutch], inp.slip_rpm(clutch),
                                 max(self.P_cmd[clutch], inp.pressure_mpa(clutch)))
        return min(torque / per_mpa, self.cal.speed.P_max_mpa)

    def force_capacity(self, clutch: str, inp: TcuInputs) -> float:
        """Largest wheel force the clutch gives at the pressure limit [N]."""
        c, P_max = self.cal.clutch(clutch), self.cal.speed.P_max_mpa
        per_mpa = torque_per_mpa(self.cal.friction, c, self._T_pred[clutch], inp.slip_rpm(clutch), P_max)
        return per_mpa * P_max * self.cal.vehicle.eta / c.speed_ratio_m

    # ---- the thermal limits ----------------------------------------------------------------------------------
    def crossover_rise_k(self, clutch: str, heat_w: float) -> float:
        """Worst rise of an off-going plate after the decision [K]: its friction power falls linearly to zero over
        the handover (half of it on average), its pressure lags the command by the hydraulic lag, and the decision
        itself may come one control period late. Cooling is neglected (conservative)."""
        s = self.cal.strategy
        return heat_w * (0.5 * s.handover_time_s + s.hydraulic_lag_s + self.dt) / self.cal.clutch(clutch).C_plate_j_k

    def limit(self, clutch: str, heat_w: float | None = None) -> float:
        """Predicted plate temperature at which the clutch must start handing over [degC]:
        T_safe - worst prediction error - the rise still coming during the crossover."""
        s = self.cal.strategy
        heat = self.heat[clutch] if heat_w is None else heat_w
        return s.T_safe_c - s.prediction_error_k - self.crossover_rise_k(clutch, heat)

    def can_take_over(self, clutch: str) -> bool:
        """The clutch may take the load if its estimate is ``takeover_headroom_k`` under its limit, the limit taken at
        the largest friction power of the two now (the on-coming clutch will carry the same wheel force)."""
        load = max(self.heat.values())
        return self._T_pred[clutch] <= self.limit(clutch, load) - self.cal.strategy.takeover_headroom_k

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
        if not inp.plant_valid:
            if self.state != "FAULT":
                self.state, self.active, self.brake_request = "FAULT", "NONE", False
                self._open_both()
            return self._outputs(faults | FAULT_PLANT_MISSING)
        self._predict(inp, dt, now)
        if self.state == "FAULT":
            self.state = "IDLE"

        if self.state == "STOPPED_OVERHEAT":
            if not inp.creep_request:
                self.state, self.brake_request = "IDLE", False
                self._open_both()
            else:
                x = 1.0 if self.cal.strategy.stop_release_s <= 0 else min(
                    (now - self.stop_t0) / self.cal.strategy.stop_release_s, 1.0)
                self.P_cmd = {c: P * (1.0 - x) for c, P in self.stop_P0.items()}
            return self._outputs(faults)

        pedal = inp.brake_pct >= BRAKE_PRESSED_PCT
        if not (inp.creep_request and not pedal) or self.starting(now):
            self._idle(inp, now, pedal)
            return self._outputs(faults)

        if self.state == "IDLE":
            first = "CL" if self.can_take_over("CL") else "CH"
            if not self.can_take_over(first):
                return self._stop(now, faults)
            self.state, self.active = "ENGAGE", first
            self.near_limit_since = None
            self.F_cmd = self.cal.launch.F_prefill_n
            self.brake_request = self.brake_request and abs(inp.v_mps) < self.cal.launch.standstill_mps

        self.hold_since = None
        step = self.cal.launch.accel_mps2 * dt
        self.v_ref = min(max(inp.desired_speed_mps, self.v_ref - step), self.v_ref + step)
        v_err = self.v_ref - inp.v_mps
        if self.state == "ENGAGE":
            P = self.P_cmd[self.active] = self.pressure_for(self.active, self.F_cmd, inp)
            if inp.pressure_mpa(self.active) >= self.cal.launch.prefill_ready_fraction * P:
                self.state, self.brake_request = "CREEP", False
                self.pid.reset(self.F_cmd)
                self.v_ref = max(inp.v_mps, 0.0)
        elif self.state == "CREEP":
            self.F_cmd = self._speed_control(v_err, dt, self.active, inp)
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

        if self.state in ("CREEP", "ENGAGE") and self._limit_reached(now):
            other = OTHER[self.active]
            if not self.can_take_over(other):
                return self._stop(now, faults)
            if self.state == "ENGAGE":  # hold the pre-fill on the other clutch, as a fresh engage
                self.P_cmd[self.active], self.active = 0.0, other
                self.near_limit_since = None
                return self._outputs(faults)
            self.state, self.handover_from, self.active = "HANDOVER", self.active, other
            self.handover_t0 = now
            self.near_limit_since = None
        return self._outputs(faults)

    def _speed_control(self, v_err: float, dt: float, clutch: str, inp: TcuInputs, share: float = 1.0) -> float:
        """PI on speed with a wheel-force output limited to what the clutches can give (anti-windup)."""
        cap = self.force_capacity(clutch, inp)
        if share < 1.0:
            cap = min(cap / max(share, 1e-3), self.force_capacity(self.handover_from, inp) / max(1.0 - share, 1e-3))
        self.pid.out_max = cap
        return self.pid.update(v_err, dt)

    def _idle(self, inp: TcuInputs, now: float, pedal: bool) -> None:
        """No creep wanted (or not yet allowed): clutches open; hill-hold while standing on the brake, for at most
        hold_max_s after."""
        self.state, self.active = "IDLE", "NONE"
        self._open_both()
        standing = abs(inp.v_mps) < self.cal.launch.standstill_mps
        if pedal and standing:
            self.brake_request, self.hold_since = True, None
        elif self.brake_request:
            if self.hold_since is None:
                self.hold_since = now
            if now - self.hold_since >= self.cal.launch.hold_max_s:
                self.brake_request, self.hold_since = False, None

    def _open_both(self) -> None:
        self.P_cmd = {"CL": 0.0, "CH": 0.0}
        self.F_cmd = 0.0
        self.pid.reset(0.0)

    def _stop(self, now: float, faults: int) -> TcuOutputs:
        self.state, self.active, self.brake_request = "STOPPED_OVERHEAT", "NONE", True
        self.stop_t0, self.stop_P0 = now, dict(self.P_cmd)
        self.F_cmd = 0.0
        return self._outputs(faults)

    def _outputs(self, faults: int) -> TcuOutputs:
        T = self.T_pred or {"CL": 0.0, "CH": 0.0}
        return TcuOutputs(self.P_cmd["CL"], self.P_cmd["CH"], self.state, self.active, self.brake_request,
                          T["CL"], T["CH"], faults)
