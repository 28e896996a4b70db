"""The creep strategy with a fake clock: engage CL first, PI tracking, handover at 250 degC, stop, faults."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from ecu_stub.calibration import TcuCalibration
from ecu_stub.controller import CreepController, TcuInputs
from ecu_stub.pid import PID
from ecu_stub.thermal_model import heat_estimate, predict_step

DT = 0.01
CREEP = TcuInputs(plant_valid=True, clutch_in_rpm=150.0, cl_out_rpm=50.0, ch_out_rpm=30.0, v_mps=0.0,
                  T_oil_CL_c=100.0, T_oil_CH_c=100.0, creep_request=True, brake_pct=0.0, desired_speed_mps=0.1)


class Clock:
    def __init__(self):
        self.t = 0.0

    def tick(self):
        self.t += DT
        return self.t


def run(ctrl, clock, inputs, seconds):
    out = None
    for _ in range(int(round(seconds / DT))):
        out = ctrl.update(inputs, clock.tick())
    return out


def test_idle_until_the_driver_asks_and_releases_the_brake():
    ctrl, clock = CreepController(), Clock()
    out = run(ctrl, clock, replace(CREEP, creep_request=False), 1.0)
    assert out.state == "IDLE" and out.P_CL_cmd_mpa == out.P_CH_cmd_mpa == 0.0
    out = run(ctrl, clock, replace(CREEP, brake_pct=50.0), 1.0)
    assert out.state == "IDLE"


def test_engages_cl_first_along_a_ramp_then_tracks_speed():
    cal = TcuCalibration()
    ctrl, clock = CreepController(cal), Clock()
    out = run(ctrl, clock, CREEP, 0.5)
    assert out.state == "ENGAGE" and out.active_clutch == "CL" and out.P_CH_cmd_mpa == 0.0
    assert out.P_CL_cmd_mpa == pytest.approx(0.5 * cal.engage_rate_mpa_s, rel=0.05)
    out = run(ctrl, clock, replace(CREEP, v_mps=0.05), 0.02)  # moving: CREEP with a bumpless PI start
    assert out.state == "CREEP"
    P0 = out.P_CL_cmd_mpa
    out = run(ctrl, clock, replace(CREEP, v_mps=0.05), 0.5)  # too slow: more pressure
    assert out.P_CL_cmd_mpa > P0
    P1 = out.P_CL_cmd_mpa
    out = run(ctrl, clock, replace(CREEP, v_mps=0.2), 0.5)  # too fast: less
    assert out.P_CL_cmd_mpa < P1


def test_hands_over_to_ch_at_250_predicted_and_back_then_stops():
    cal = TcuCalibration()
    ctrl, clock = CreepController(cal), Clock()
    run(ctrl, clock, replace(CREEP, v_mps=0.1), 1.0)
    assert ctrl.state == "CREEP" and ctrl.active == "CL"
    P_before = ctrl.P_cmd["CL"]
    ctrl.T_pred["CL"] = 251.0  # the prediction reaches the safety temperature (cools 0.3 K in a cycle)
    out = ctrl.update(replace(CREEP, v_mps=0.1), clock.tick())
    assert out.state == "HANDOVER" and out.active_clutch == "CH"
    out = run(ctrl, clock, replace(CREEP, v_mps=0.1), cal.handover_time_s / 2)
    assert 0.0 < out.P_CL_cmd_mpa < P_before and out.P_CH_cmd_mpa > 0.0  # crossing over
    out = run(ctrl, clock, replace(CREEP, v_mps=0.1), cal.handover_time_s)
    assert out.state == "CREEP" and out.active_clutch == "CH" and out.P_CL_cmd_mpa == 0.0
    assert out.P_CH_cmd_mpa == pytest.approx(P_before * cal.i_L / cal.i_H, rel=0.1)  # same wheel torque
    # CH hot, CL cooled enough: back to CL
    ctrl.T_pred["CH"], ctrl.T_pred["CL"] = 251.0, 205.5
    out = ctrl.update(replace(CREEP, v_mps=0.1), clock.tick())
    assert out.state == "HANDOVER" and out.active_clutch == "CL"
    run(ctrl, clock, replace(CREEP, v_mps=0.1), cal.handover_time_s + 0.1)
    # CL hot again and CH not cool enough to take over: stop, release both, ask for the brake
    ctrl.T_pred["CL"], ctrl.T_pred["CH"] = 251.0, cal.T_safe_c - cal.takeover_margin_c + 1.0
    out = ctrl.update(replace(CREEP, v_mps=0.1), clock.tick())
    assert out.state == "STOPPED_OVERHEAT" and out.brake_request
    assert out.P_CL_cmd_mpa == out.P_CH_cmd_mpa == 0.0 and out.active_clutch == "NONE"
    out = run(ctrl, clock, replace(CREEP, v_mps=0.0), 5.0)  # latched while the driver keeps asking
    assert out.state == "STOPPED_OVERHEAT" and out.brake_request
    out = ctrl.update(replace(CREEP, creep_request=False), clock.tick())
    assert out.state == "IDLE" and not out.brake_request


def test_missing_plant_frames_open_both_clutches():
    ctrl, clock = CreepController(), Clock()
    run(ctrl, clock, replace(CREEP, v_mps=0.1), 1.0)
    out = ctrl.update(TcuInputs(plant_valid=False), clock.tick())
    assert out.state == "FAULT" and out.fault_bits & 0x01 and out.P_CL_cmd_mpa == out.P_CH_cmd_mpa == 0.0
    out = ctrl.update(replace(CREEP, creep_request=False), clock.tick())
    assert out.state == "IDLE" and out.fault_bits == 0


def test_time_must_advance():
    ctrl = CreepController()
    ctrl.update(CREEP, 1.0)
    with pytest.raises(ValueError):
        ctrl.update(CREEP, 1.0)


def test_temperature_predictor_by_hand():
    cal = TcuCalibration()
    Q = heat_estimate(0.5, 100.0, cal)
    assert Q == pytest.approx(cal.mu_nom * cal.k_geom_m3 * 0.5e6 * 100.0 * 2 * math.pi / 60)
    T = 100.0
    for _ in range(100):
        T = predict_step(T, Q, 90.0, 1.0, cal)
    assert T == pytest.approx(90.0 + Q / cal.K_plate_oil_w_k, rel=1e-6)
    tau = cal.C_plate_j_k / cal.K_plate_oil_w_k
    assert predict_step(100.0, 0.0, 90.0, tau, cal) == pytest.approx(90.0 + 10.0 / math.e)


def test_pid_anti_windup_rate_limit_and_bad_dt():
    pid = PID(kp=1.0, ki=10.0, out_min=0.0, out_max=1.0, rate_limit=1.0)
    pid.reset(0.0)
    outs = [pid.update(5.0, 0.1) for _ in range(50)]
    assert outs[0] == pytest.approx(0.1) and max(outs) == 1.0  # rate-limited rise to the limit
    assert pid.integral <= 1.0  # no wind-up while saturated
    assert pid.update(-0.5, 0.1) < 1.0  # comes off the limit at once when the error turns
    with pytest.raises(ValueError):
        pid.update(1.0, 0.0)
