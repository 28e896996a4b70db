"""The creep strategy of the paper (Fig. 7, Section V): ``CreepController.update(inputs, now) -> outputs``.

No bus, no clock: time is passed in, so the strategy is tested with a fake clock and can run behind any bus.

* IDLE: both clutches open; waits for the driver's creep request with the brake released.
* ENGAGE: the on-coming clutch (CL first) fills along a pressure ramp until the vehicle moves.
* CREEP: a PI controller on vehicle speed sets that clutch's pressure (anti-windup, rate limit).
* HANDOVER: when the slipping clutch's *predicted* plate temperature reaches T_safe (250 degC) and the other
  clutch is predicted below T_safe - margin, the slipping clutch is released and the other engaged, pressures
  crossing over ``handover_time_s``; control continues on the new clutch without a bump.
* STOPPED_OVERHEAT: when neither can take over, both clutches are released and the brake is requested. Latched
  until the driver withdraws the creep request.
* FAULT: plant frames missing or invalid: both clutches open, fault bit set; back to IDLE when they return.
"""

from __future__ import annotations

from dataclasses import dataclass

from .calibration import TcuCalibration
from .pid import PID
from .thermal_model import heat_estimate, predict_step

OTHER = {"CL": "CH", "CH": "CL"}
FAULT_PLANT_MISSING = 0x01


@dataclass(frozen=True)
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
    creep_request: bool = False
    brake_pct: float = 0.0
    desired_speed_mps: float = 0.0
    fault_bits: int = 0  # protocol faults seen by the runner (CRC, counter, range)


@dataclass(frozen=True)
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
        self.cal = cal or TcuCalibration()
        c = self.cal
        self.pid = PID(c.kp_mpa_per_mps, c.ki_mpa_per_m, c.kd_mpa_s2_per_m, c.P_min_mpa, c.P_max_mpa, c.P_rate_mpa_s)
        self.state = "IDLE"
        self.active = "NONE"
        self.T_pred: dict[str, float] | None = None
        self.P_cmd = {"CL": 0.0, "CH": 0.0}
        self.last_now: float | None = None
        self.handover_from = "NONE"
        self.handover_t0 = 0.0
        self.handover_P0 = 0.0
        self.handover_target = 0.0

    # ---- helpers ---------------------------------------------------------------------------------------------
    def _can_take(self, clutch: str) -> bool:
        return self.T_pred[clutch] < self.cal.T_safe_c - self.cal.takeover_margin_c

    def _predict(self, inp: TcuInputs, dt: float) -> None:
        if self.T_pred is None:  # first sight: plates at the temperature of the oil leaving them
            self.T_pred = {"CL": inp.T_oil_CL_c, "CH": inp.T_oil_CH_c}
            return
        slips = {"CL": inp.clutch_in_rpm - inp.cl_out_rpm, "CH": inp.clutch_in_rpm - inp.ch_out_rpm}
        pressures = {"CL": inp.P_CL_mpa, "CH": inp.P_CH_mpa}
        oil = {"CL": inp.T_oil_CL_c, "CH": inp.T_oil_CH_c}
        for c in ("CL", "CH"):
            heat = heat_estimate(pressures[c], slips[c], self.cal)
            self.T_pred[c] = predict_step(self.T_pred[c], heat, oil[c], dt, self.cal)

    def _open_both(self) -> None:
        self.P_cmd = {"CL": 0.0, "CH": 0.0}
        self.pid.reset(0.0)

    # ---- the strategy ------------------------------------------------------------------------------------------
    def update(self, inp: TcuInputs, now: float) -> TcuOutputs:
        dt = 0.01 if self.last_now is None else now - self.last_now
        if self.last_now is not None and not dt > 0.0:
            raise ValueError(f"time must advance: {now} after {self.last_now}")
        self.last_now = now
        faults = inp.fault_bits
        if not inp.plant_valid:
            if self.state != "FAULT":
                self.state, self.active = "FAULT", "NONE"
                self._open_both()
            return self._outputs(faults | FAULT_PLANT_MISSING, brake=False)
        self._predict(inp, dt)
        if self.state == "FAULT":
            self.state = "IDLE"
        wants_creep = inp.creep_request and inp.brake_pct < 5.0

        if self.state == "STOPPED_OVERHEAT":
            if not inp.creep_request:
                self.state = "IDLE"
            return self._outputs(faults, brake=self.state == "STOPPED_OVERHEAT")

        if not wants_creep:
            self.state, self.active = "IDLE", "NONE"
            self._open_both()
            return self._outputs(faults, brake=False)

        if self.state == "IDLE":
            first = "CL" if self._can_take("CL") else "CH"
            if not self._can_take(first):
                return self._stop(faults)
            self.state, self.active = "ENGAGE", first
            self.pid.reset(0.0)

        c = self.cal
        v_err = inp.desired_speed_mps - inp.v_mps
        if self.state == "ENGAGE":
            P = min(self.P_cmd[self.active] + c.engage_rate_mpa_s * dt, c.P_max_mpa)
            self.P_cmd[self.active] = P
            if inp.v_mps >= c.engage_speed_fraction * inp.desired_speed_mps or P >= c.P_max_mpa:
                self.state = "CREEP"
                self.pid.reset(P)
        elif self.state == "CREEP":
            self.P_cmd[self.active] = self.pid.update(v_err, dt)
            self.P_cmd[OTHER[self.active]] = 0.0
        elif self.state == "HANDOVER":
            x = min((now - self.handover_t0) / c.handover_time_s, 1.0)
            self.P_cmd[self.handover_from] = self.handover_P0 * (1.0 - x)
            self.P_cmd[self.active] = self.handover_target * x
            if x >= 1.0:
                self.state = "CREEP"
                self.pid.reset(self.handover_target)

        if self.state in ("CREEP", "ENGAGE") and self.T_pred[self.active] >= c.T_safe_c:
            other = OTHER[self.active]
            if not self._can_take(other):
                return self._stop(faults)
            self.state, self.handover_from, self.active = "HANDOVER", self.active, other
            self.handover_t0, self.handover_P0 = now, self.P_cmd[self.handover_from]
            # same torque at the wheel on the other gear: pressure scales with the ratio of the two gears
            ratio = c.i_L / c.i_H if other == "CH" else c.i_H / c.i_L
            self.handover_target = min(self.handover_P0 * ratio, c.P_max_mpa)
        return self._outputs(faults, brake=False)

    def _stop(self, faults: int) -> TcuOutputs:
        self.state, self.active = "STOPPED_OVERHEAT", "NONE"
        self._open_both()
        return self._outputs(faults, brake=True)

    def _outputs(self, faults: int, brake: bool) -> TcuOutputs:
        T = self.T_pred or {"CL": 0.0, "CH": 0.0}
        return TcuOutputs(self.P_cmd["CL"], self.P_cmd["CH"], self.state, self.active, brake, T["CL"], T["CH"],
                          faults)
