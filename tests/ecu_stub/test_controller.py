"""The creep strategy with a fake clock: hill-hold and pre-fill, PI tracking, torque handover, the thermal limit and
its margin, dwell, start-up assumption, stop when neither clutch can take over (and not before), faults."""

from __future__ import annotations

import ast
import dataclasses
import math
from dataclasses import replace

import pytest

from ecu_stub.calibration import FrictionMap, load_calibration
from ecu_stub.clutch_model import SLIP_FILTER_S, friction_coefficient, friction_heat, plate_step
from ecu_stub.controller import CreepController, TcuInputs, TcuOutputs
from ecu_stub.monitor import MonitorVerdict
from ecu_stub.pid import PID
from ecu_stub.sensor_checks import OIL_FALL_K

from ..source import definition

DT = 0.01
CAL = load_calibration()
# a flat map, so that heat and pressures are easy to compute by hand in these tests
FLAT = replace(CAL, friction=FrictionMap((20.0, 320.0), (0.0, 400.0), (0.0, 1.5), (((0.07,) * 2,) * 2,) * 2))
CREEP = TcuInputs(plant_valid=True, clutch_in_rpm=150.0, cl_out_rpm=50.0, ch_out_rpm=30.0, v_mps=0.0,
                  T_oil_CL_c=100.0, T_oil_CH_c=100.0, creep_request=True, brake_pct=0.0, desired_speed_mps=0.2)
BRAKED = replace(CREEP, creep_request=False, brake_pct=100.0)


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


def creeping(cal=FLAT, clutch="CL"):
    """A controller in CREEP on CL at the desired speed, the pre-fill done; plates at the oil temperature."""
    ctrl, clock = CreepController(cal), Clock()
    run(ctrl, clock, BRAKED, cal.strategy.startup_observer_s + 0.1)
    out = run(ctrl, clock, replace(CREEP, P_CL_mpa=1.0, v_mps=0.2), 0.05)
    assert out.state == "CREEP" and out.active_clutch == clutch
    ctrl.T_pred = {"CL": 100.0, "CH": 100.0}
    return ctrl, clock


def hold_at(ctrl, clock, inp, T_CL, T_CH):
    """Put the estimates at (T_CL, T_CH) with the oil at the same temperatures and no slip (no drift), one cycle."""
    ctrl.T_pred = {"CL": T_CL, "CH": T_CH}
    return ctrl.update(replace(inp, T_oil_CL_c=T_CL, T_oil_CH_c=T_CH), clock.tick())


def test_idle_holds_the_vehicle_unless_the_driver_brakes_it_himself():
    ctrl, clock = CreepController(FLAT), Clock()
    out = run(ctrl, clock, BRAKED, 1.0)
    assert out.state == "IDLE" and out.brake_request and out.P_CL_cmd_mpa == out.P_CH_cmd_mpa == 0.0
    released = replace(BRAKED, brake_pct=0.0)  # foot off, no creep request: held, however long
    out = run(ctrl, clock, released, 30.0)
    assert out.state == "IDLE" and out.brake_request
    out = run(ctrl, clock, replace(released, v_mps=1.0), 0.1)  # moving, nobody braking: stopped and held
    assert out.brake_request
    # it stood held since its last launch: held whatever the speed reads under his pedal (issue 37: a VehicleSpeed
    # reading -14.5 mm/s off, within the speed vote, ended the hold under a 6.3 % pedal: 8.2 m of roll-back)
    out = run(ctrl, clock, replace(BRAKED, v_mps=0.9), 0.1)
    assert out.brake_request and ctrl.stand_held
    ctrl, clock = CreepController(FLAT), Clock()  # moving, never held standing: stopped by the TCU while nobody
    out = run(ctrl, clock, replace(released, v_mps=1.0), 0.1)  # brakes, and left to him once he brakes it
    assert out.brake_request and not ctrl.stand_held
    out = run(ctrl, clock, replace(BRAKED, v_mps=0.9), 0.1)  # slowed by the driver's brake: his to control
    assert not out.brake_request
    # speeding up under his pressed pedal (issue 37: a light pedal downhill): it does not hold the vehicle, so the
    # TCU requests the brake until it stands (before: left to the pedal, 8.5 m/s on -0.30 rad)
    out = ctrl.update(replace(BRAKED, v_mps=0.95), clock.tick())
    assert out.brake_request
    out = run(ctrl, clock, replace(BRAKED, v_mps=0.9), 0.1)  # latched while it moves
    assert out.brake_request
    out = ctrl.update(TcuInputs(plant_valid=False), clock.tick())  # FAULT: held too
    assert out.state == "FAULT" and out.brake_request


def test_a_pedal_not_holding_the_vehicle_backwards_is_overruled():
    """Rolling back beyond the standstill band and speeding up under a pressed pedal (too light for the slope; no
    creep asks to roll back): the brake is requested until the vehicle stands."""
    ctrl, clock = CreepController(FLAT), Clock()
    run(ctrl, clock, replace(BRAKED, brake_pct=0.0, v_mps=-0.05), 0.1)  # rolling back, nobody braking, then he does
    out = run(ctrl, clock, replace(BRAKED, v_mps=-0.05), 0.1)  # rolling back steadily under it: his to control
    assert not out.brake_request
    out = ctrl.update(replace(BRAKED, v_mps=-0.06), clock.tick())  # speeding up backwards
    assert out.brake_request and ctrl.pedal_overrun
    out = run(ctrl, clock, replace(BRAKED, v_mps=-0.05), 0.1)  # latched while it moves
    assert out.brake_request


def test_a_braked_vehicle_whose_speed_reads_steady_within_what_the_vote_lets_through_stands():
    """VehicleSpeed read 14.5 mm/s off at a standstill (beyond the 10-mm/s band; the vote out-votes it after about
    3 s): under the pedal, steady for STEADY_S, it stands: held, and kept held when the pedal gets light; a steady
    reading beyond what the vote lets through, or one that changes, is motion."""
    ctrl, clock = CreepController(FLAT), Clock()
    off = replace(BRAKED, v_mps=-0.0145)
    out = ctrl.update(off, clock.tick())
    assert not ctrl.still  # not yet steady
    out = run(ctrl, clock, off, 0.11)
    assert ctrl.still and out.brake_request and ctrl.stand_held
    out = run(ctrl, clock, replace(off, brake_pct=6.0), 1.0)
    assert out.brake_request
    ctrl, clock = CreepController(FLAT), Clock()
    run(ctrl, clock, replace(BRAKED, brake_pct=0.0, v_mps=0.05), 0.1)  # moving, stopped by the TCU: not standing
    run(ctrl, clock, replace(BRAKED, v_mps=0.035), 0.5)
    assert not ctrl.still and not ctrl.stand_held


def test_engage_prefills_under_the_brake_then_releases_it_and_tracks_speed():
    ctrl, clock = CreepController(FLAT), Clock()
    run(ctrl, clock, BRAKED, FLAT.strategy.startup_observer_s + 0.1)
    out = ctrl.update(CREEP, clock.tick())  # driver releases and asks to creep; pressure not there yet
    assert out.state == "ENGAGE" and out.active_clutch == "CL" and out.brake_request and out.P_CH_cmd_mpa == 0.0
    c = FLAT.CL
    P_pre = FLAT.launch.F_prefill_n * c.speed_ratio_m / FLAT.vehicle.eta / (0.07 * c.k_geom_m3 * 1e6)
    assert out.P_CL_cmd_mpa == pytest.approx(P_pre, rel=1e-9)  # the whole pre-fill at once
    out = run(ctrl, clock, replace(CREEP, P_CL_mpa=0.8 * P_pre), 0.1)
    assert out.state == "ENGAGE" and out.brake_request  # held until 90 % of the pressure is measured
    out = ctrl.update(replace(CREEP, P_CL_mpa=0.95 * P_pre), clock.tick())
    assert out.state == "CREEP" and not out.brake_request
    assert out.P_CL_cmd_mpa == pytest.approx(P_pre, rel=0.02)  # bumpless from the pre-fill
    run(ctrl, clock, replace(CREEP, P_CL_mpa=P_pre), 0.5)
    assert ctrl.v_ref == pytest.approx(0.51 * FLAT.launch.accel_mps2, rel=0.05)  # the reference ramps up: no step
    slow = run(ctrl, clock, replace(CREEP, P_CL_mpa=P_pre, v_mps=0.1), 1.0)
    assert ctrl.v_ref == 0.2 and slow.P_CL_cmd_mpa > P_pre  # too slow: more force
    fast = run(ctrl, clock, replace(CREEP, P_CL_mpa=P_pre, v_mps=0.3), 0.6)
    assert fast.P_CL_cmd_mpa < slow.P_CL_cmd_mpa


def standing(grade_rad, cal=CAL):
    """A controller in IDLE, held on the brake, its accelerometer reading g sin(grade) (dv/dt 0)."""
    ctrl, clock = CreepController(cal), Clock()
    run(ctrl, clock, replace(BRAKED, accel_mps2=9.81 * math.sin(grade_rad)), cal.strategy.startup_observer_s + 0.1)
    return ctrl, clock


@pytest.mark.parametrize("grade, prefill_n", [
    # the heaviest, 11,760 kg: m g (sin a - f cos a) = 115,365.6 N x (0.198669 - 0.123 x 0.980067)
    (0.2, 9012.2),
    # 115,365.6 x (0.247404 - 0.123 x 0.968912) = 14,793 N would push the lightest off: 0.85 of its road load,
    # 0.85 x 38,455.2 N x (0.247404 + 0.123 x 0.968912) = 11,982.3 N
    (0.25, 11982.3),
    (0.5, 11982.3),  # a reading beyond the steepest grade (a faulty one): taken as 0.25 rad
    (0.1, 7850.0),  # m g (sin a - f cos a) < 0: the least pre-fill, launch.F_prefill_n
    (-0.15, 7850.0),
])
def test_a_first_launch_prefills_for_the_grade_read_at_the_standstill(grade, prefill_n):
    ctrl, clock = standing(grade)
    assert ctrl.prefill_force() == pytest.approx(prefill_n, rel=2e-4)
    out = ctrl.update(replace(CREEP, accel_mps2=9.81 * math.sin(grade)), clock.tick())
    assert out.state == "ENGAGE" and ctrl.F_cmd == pytest.approx(prefill_n, rel=2e-4)


def test_the_grade_is_read_only_while_the_vehicle_stands_held():
    ctrl, clock = standing(0.2)
    s = ctrl.sin_grade
    assert s == pytest.approx(math.sin(0.2), abs=1e-12)
    run(ctrl, clock, replace(BRAKED, v_mps=0.1, accel_mps2=-3.0), 0.1)  # braking a moving vehicle: dv/dt in it
    run(ctrl, clock, replace(CREEP, v_mps=0.05, accel_mps2=4.0), 0.1)  # launching
    assert ctrl.sin_grade == s


def test_after_a_settled_creep_the_prefill_is_the_learned_weight_times_sin_a():
    """The settled creep's force is the road load m g (sin a + f cos a): the pre-fill m g sin a is the middle of
    the window where a standing vehicle stays."""
    ctrl, clock = standing(0.2, FLAT)
    run(ctrl, clock, replace(CREEP, P_CL_mpa=1.0, v_mps=0.2), 0.5)
    assert ctrl.state == "CREEP" and ctrl.F_creep > 0.0
    s, c = math.sin(0.2), math.cos(0.2)
    weight_n = ctrl.F_creep / (s + 0.123 * c)
    assert ctrl.prefill_force() == pytest.approx(max(weight_n * s, 7850.0), rel=1e-9)


@pytest.mark.parametrize("pedal, ramped", [(0.0, True), (100.0, False)])
def test_creep_withdrawn_without_the_brake_ramps_the_clutch_out_while_the_brake_comes_in(pedal, ramped):
    """Without the driver's brake, the TCU's brake request reaches the brakes with the next TCU_STATUS (100 ms):
    the clutch ramps out over stop_release_s meanwhile (as at a stop). With the pedal pressed it opens at once."""
    ctrl, clock = creeping()
    P0 = ctrl.P_cmd["CL"]
    assert P0 > 0.1
    withdrawn = replace(CREEP, creep_request=False, brake_pct=pedal, v_mps=0.2, P_CL_mpa=P0)
    out = ctrl.update(withdrawn, clock.tick())
    assert out.state == "IDLE" and out.brake_request == (not pedal)
    release_s = FLAT.strategy.stop_release_s
    assert out.P_CL_cmd_mpa == (P0 if ramped else 0.0)  # the ramp starts from the last command
    out = run(ctrl, clock, withdrawn, release_s / 2)
    assert out.P_CL_cmd_mpa == (pytest.approx(P0 * 0.5) if ramped else 0.0)
    out = run(ctrl, clock, withdrawn, release_s)
    assert out.P_CL_cmd_mpa == out.P_CH_cmd_mpa == 0.0 and not ctrl.releasing


def test_limit_is_t_safe_minus_prediction_error_minus_crossover_rise():
    ctrl, clock = creeping()
    inp = replace(CREEP, P_CL_mpa=0.6, v_mps=0.2)
    ctrl.update(inp, clock.tick())
    s = FLAT.strategy
    Q = 0.07 * FLAT.CL.k_geom_m3 * 0.6e6 * 100.0 * 2 * math.pi / 60  # mu k P slip (100 r/min)
    assert ctrl.heat["CL"] == pytest.approx(Q, rel=1e-3)
    # the crossover's power: at the larger of command and measured pressure (the monitor's), at the slip of the
    # vehicle at its desired speed: 150 r/min in, 0.2 m/s / r_CL = 55.45 r/min out, if under the present 100 r/min
    P = max(ctrl.P_cmd["CL"], 0.6)
    slip_x = 150.0 - 0.2 / FLAT.CL.speed_ratio_m * 60 / (2 * math.pi)
    assert 94.0 < slip_x < 95.0
    Q_x = 0.07 * FLAT.CL.k_geom_m3 * P * 1e6 * slip_x * 2 * math.pi / 60
    assert ctrl.crossover_heat("CL") == pytest.approx(Q_x, rel=1e-9)
    # the monitor's worst power until a release: the same pressure, and the whole input speed as slip (150 r/min:
    # the vehicle braked to rest)
    Q_w = 0.07 * FLAT.CL.k_geom_m3 * P * 1e6 * 150.0 * 2 * math.pi / 60
    rise = max(Q_x * (s.handover_time_s / 2 + s.hydraulic_lag_s + DT),  # the crossover, share 1 -> 0 linearly
               Q_w * (s.stop_release_s / 2 + s.hydraulic_lag_s + DT)) / FLAT.CL.C_plate_j_k  # the monitor's release
    # the margin for the errors the checks let through (margin_k, test_margin_budgets_...), and the rise scaled by
    # the undetected heat error
    e = ctrl.margin_k("CL")
    assert ctrl.limit("CL") == pytest.approx(s.T_safe_c - e - ctrl.heat_scale("CL") * rise, rel=1e-9)
    # no giving up early: the hotter clutch used to within 20 K (15 K before the margin budgeted an oil gain's growth,
    # docs/safety.md: about 2.5 K more here)
    assert 0.0 < e + ctrl.heat_scale("CL") * rise < 20.0


def test_the_margin_of_a_launch_budgets_the_crossover_not_the_launch():
    """A vehicle still at rest 1 s into a steep launch (the new plant's breakaway) slips the whole input speed at a
    force above the creep force; the crossover runs with the vehicle carried to its desired speed. By hand: 240
    r/min in, 0.4 m/s desired = 0.4 / 0.034474 m = 11.60 rad/s = 110.8 r/min out, so 129.2 r/min of slip instead of
    240, the same pressure (1.0 MPa, commanded and measured): Q_x = 0.07 k_geom 1 MPa 129.2 r/min."""
    ctrl, clock = creeping()
    launch = replace(CREEP, clutch_in_rpm=240.0, cl_out_rpm=0.0, ch_out_rpm=0.0, v_mps=0.0, desired_speed_mps=0.4,
                     P_CL_mpa=1.0)
    ctrl.update(launch, clock.tick())
    ctrl.P_cmd["CL"] = 1.0
    k, C, s, rpm = FLAT.CL.k_geom_m3, FLAT.CL.C_plate_j_k, FLAT.strategy, 2 * math.pi / 60
    slip_x = 240.0 - 0.4 / FLAT.CL.speed_ratio_m / rpm
    assert slip_x == pytest.approx(129.2, abs=0.1)
    Q_x = 0.07 * k * 1e6 * slip_x * rpm
    Q_now = 0.07 * k * 1e6 * 240.0 * rpm  # the launch's passing power, what the margin budgeted before
    assert ctrl.crossover_heat("CL") == pytest.approx(Q_x, rel=1e-9)
    assert ctrl.worst_heat("CL") == pytest.approx(Q_now, rel=1e-9)  # the monitor keeps the worst slip
    T = ctrl.T_pred["CL"]
    assert ctrl.limit("CL") == pytest.approx(
        s.T_safe_c - ctrl.margin_k("CL")
        - ctrl.heat_scale("CL") * max(Q_x * (s.handover_time_s / 2 + s.hydraulic_lag_s + DT),
                                      Q_now * (s.stop_release_s / 2 + s.hydraulic_lag_s + DT)) / C,
        rel=1e-9)
    assert ctrl.T_pred["CL"] == T
    # a vehicle over its target: the present (smaller) slip
    over = replace(launch, cl_out_rpm=200.0, v_mps=0.45)
    ctrl.update(over, clock.tick())
    ctrl.P_cmd["CL"] = 1.0
    assert ctrl.crossover_heat("CL") == pytest.approx(0.07 * k * 1e6 * 40.0 * rpm, rel=1e-9)


def test_torque_handover_splits_the_force_and_keeps_speed_control():
    ctrl, clock = creeping()
    inp = replace(CREEP, P_CL_mpa=0.6, v_mps=0.2)
    run(ctrl, clock, inp, 0.5)
    limit = ctrl.limit("CL", 0.0)
    still = replace(inp, clutch_in_rpm=0.0, cl_out_rpm=0.0, ch_out_rpm=0.0)  # no slip possible: no heat to come
    out = hold_at(ctrl, clock, still, limit - 0.05, 150.0)
    assert out.state == "CREEP"  # just under: not yet
    out = hold_at(ctrl, clock, still, limit + 0.05, 150.0)
    assert out.state == "HANDOVER" and out.active_clutch == "CH"
    F0 = ctrl.F_cmd
    out = run(ctrl, clock, inp, FLAT.strategy.handover_time_s / 2)
    x = 0.5
    assert out.P_CL_cmd_mpa == pytest.approx(ctrl.pressure_for("CL", (1 - x) * ctrl.F_cmd, inp), rel=0.05)
    assert out.P_CH_cmd_mpa == pytest.approx(ctrl.pressure_for("CH", x * ctrl.F_cmd, inp), rel=0.05)
    # wheel force from both clutches, by the TCU's own model, is the speed controller's demand
    wheel = sum(P * 0.07 * c.k_geom_m3 * 1e6 * FLAT.vehicle.eta / c.speed_ratio_m
                for P, c in ((out.P_CL_cmd_mpa, FLAT.CL), (out.P_CH_cmd_mpa, FLAT.CH)))
    assert wheel == pytest.approx(ctrl.F_cmd, rel=0.03)
    out = run(ctrl, clock, replace(inp, v_mps=0.1), 0.2)  # the vehicle slows: the controller still acts
    assert ctrl.F_cmd > F0 and out.state == "HANDOVER"
    out = run(ctrl, clock, inp, FLAT.strategy.handover_time_s)
    assert out.state == "CREEP" and out.active_clutch == "CH" and out.P_CL_cmd_mpa == 0.0 and out.P_CH_cmd_mpa > 0


def test_a_plate_kept_just_under_its_limit_is_acted_on_after_the_dwell_time():
    ctrl, clock = creeping()
    inp = replace(CREEP, clutch_in_rpm=50.0, cl_out_rpm=50.0, ch_out_rpm=50.0, v_mps=0.2)  # no slip: no heat
    s = FLAT.strategy
    limit = ctrl.limit("CL", 0.0)
    for _ in range(int((s.dwell_time_s - 0.5) / DT)):
        out = hold_at(ctrl, clock, inp, limit - 0.5 * s.dwell_band_k, 150.0)
    assert out.state == "CREEP"
    for _ in range(int(1.0 / DT)):
        out = hold_at(ctrl, clock, inp, limit - 0.5 * s.dwell_band_k, 150.0)
    assert out.state == "HANDOVER" and out.active_clutch == "CH"
    ctrl2, clock2 = creeping()  # further below the band: never
    for _ in range(int((s.dwell_time_s + 5) / DT)):
        out = hold_at(ctrl2, clock2, inp, limit - 1.5 * s.dwell_band_k, 150.0)
    assert out.state == "CREEP"


def test_the_pressure_for_a_force_takes_the_slip_low_passed_not_a_ringing_output_shaft():
    """By hand on a map whose mu falls with slip: the pressure for a wheel force uses the slip through a first-order
    low-pass of SLIP_FILTER_S (0.1 s). Settled at 100 r/min, the output speed of one cycle does not move it; an
    output shaft ringing 0 / 100 r/min cycle by cycle leaves it within 3 r/min of the mean; a step of the slip from
    100 to 50 r/min reaches 100 - 50 (1 - e^-1) = 68.4 r/min after 0.1 s."""
    slope = replace(FLAT, friction=FrictionMap((20.0, 320.0), (0.0, 400.0), (0.0, 1.5),
                                               (((0.10, 0.10), (0.06, 0.06)),) * 2))  # mu falls with slip
    ctrl, clock = creeping(slope)
    inp = replace(CREEP, P_CL_mpa=0.6, v_mps=0.2)  # 150 r/min in, CL out 50: slip 100 r/min
    run(ctrl, clock, inp, 1.0)
    F = 20000.0

    def by_hand(slip):
        mu = friction_coefficient(slope.friction, ctrl.T_pred["CL"], slip, max(ctrl.P_cmd["CL"], 0.6))
        return F * slope.CL.speed_ratio_m / slope.vehicle.eta / (mu * slope.CL.k_geom_m3 * 1e6)

    assert ctrl.mean_slip_rpm("CL", inp) == pytest.approx(100.0, abs=1e-3)
    for out_rpm in (0.0, 50.0, 140.0):
        assert ctrl.pressure_for("CL", F, replace(inp, cl_out_rpm=out_rpm)) == pytest.approx(by_hand(100.0), rel=1e-4)
    for k in range(100):  # ringing: the output at 0 and 100 r/min in turn, the slip 150 and 50 about 100
        ctrl.update(replace(inp, cl_out_rpm=0.0 if k % 2 else 100.0), clock.tick())
    assert abs(ctrl.mean_slip_rpm("CL", inp) - 100.0) < 3.0
    run(ctrl, clock, inp, 1.0)
    run(ctrl, clock, replace(inp, cl_out_rpm=100.0), 0.1)  # the slip steps to 50 r/min
    assert ctrl.mean_slip_rpm("CL", inp) == pytest.approx(100.0 - 50.0 * (1.0 - math.exp(-1.0)), abs=0.1)


def test_the_plate_prediction_takes_mu_at_the_low_passed_slip_and_the_power_at_the_measured_one():
    """By hand on a map whose mu falls with slip: settled at 100 r/min, one cycle whose output shaft reads a slip
    of 50 r/min (a ringing shaft's sample) heats the plate by mu(T, mean) k P |50 r/min|, the mean low-passed over
    SLIP_FILTER_S including this cycle's sample: 100 - 50 (1 - e^-0.1) r/min, not mu at 50 r/min."""
    slope = replace(FLAT, friction=FrictionMap((20.0, 320.0), (0.0, 400.0), (0.0, 1.5),
                                               (((0.10, 0.10), (0.06, 0.06)),) * 2))  # mu falls with slip
    ctrl, clock = creeping(slope)
    inp = replace(CREEP, P_CL_mpa=0.6, v_mps=0.2)  # 150 r/min in, CL out 50: slip 100 r/min
    run(ctrl, clock, inp, 2.0)
    T = ctrl.T_pred["CL"]
    ctrl.update(replace(inp, cl_out_rpm=100.0), clock.tick())
    mean = 100.0 - 50.0 * (1.0 - math.exp(-DT / SLIP_FILTER_S))
    assert ctrl.mean_slip_rpm("CL", inp) == pytest.approx(mean, rel=1e-9)
    mu = friction_coefficient(slope.friction, T, mean, 0.6)
    assert ctrl.heat["CL"] == pytest.approx(mu * slope.CL.k_geom_m3 * 1e6 * 0.6 * 50.0 * 2 * math.pi / 60, rel=1e-9)
    assert ctrl.heat["CL"] < 0.99 * friction_heat(slope.friction, slope.CL, T, 50.0, 0.6)  # mu at 50 r/min: more


def test_the_force_at_a_pressure_takes_mu_at_that_pressure_and_inverts_the_pressure_for_a_force():
    """By hand on a map whose mu falls with pressure (0.10 at 0, 0.06 at 1.5 MPa): the wheel force at 0.3 MPa is
    mu(0.3) k_geom 0.3 eta / r with mu(0.3) = 0.092, not the force at the pressure limit scaled by 0.3 / 1.5 (mu
    0.06: 35 % short, which gave the on-coming clutch too little of what the monitor took off the off-going one in a
    handover); and the pressure for that force is 0.3 MPa again."""
    by_p = replace(FLAT, friction=FrictionMap((20.0, 320.0), (0.0, 400.0), (0.0, 1.5),
                                              tuple(((0.10, 0.06), (0.10, 0.06)) for _ in range(2))))
    ctrl, clock = creeping(by_p)
    inp = replace(CREEP, P_CL_mpa=0.3, v_mps=0.2)
    run(ctrl, clock, inp, 0.5)
    c, eta = by_p.CL, by_p.vehicle.eta
    F = ctrl.force_at("CL", 0.3, inp)
    assert F == pytest.approx(0.092 * c.k_geom_m3 * 1e6 * 0.3 * eta / c.speed_ratio_m, rel=1e-9)
    assert F > 1.5 * ctrl.force_capacity("CL", inp) * 0.3 / by_p.speed.P_max_mpa
    assert ctrl.pressure_for("CL", F, inp) == pytest.approx(0.3, rel=1e-9)


def test_the_on_coming_clutch_is_judged_on_its_own_power_once_it_carries():
    """The handover gate takes the power the on-coming clutch will have, not the present one: the same wheel force F
    needs the torque F r_c / eta on clutch c, so by hand, on CREEP's speeds (150 r/min in, 0.2 m/s desired):
    CH's crossover slip 150 - 0.2 / r_CH = 117.9 r/min and worst slip 150 r/min, each times CH's torque; with the
    clutches open (no force demanded), the pre-fill's force."""
    ctrl, clock = creeping()
    ctrl.update(replace(CREEP, P_CL_mpa=0.6, v_mps=0.2), clock.tick())
    rpm, eta, F = 2 * math.pi / 60, FLAT.vehicle.eta, ctrl.F_cmd
    assert F > 0.0
    slip_x = 150.0 - 0.2 / FLAT.CH.speed_ratio_m / rpm
    assert slip_x == pytest.approx(117.9, abs=0.1)
    M_CH = F * FLAT.CH.speed_ratio_m / eta
    assert ctrl.takeover_heat("CH") == pytest.approx((M_CH * slip_x * rpm, M_CH * 150.0 * rpm), rel=1e-9)
    # CH's torque is r_CH / r_CL = 1.73 times CL's for the same force, and it slips more at the desired speed
    # (117.9 against 94.5 r/min): the same wheel force heats CH 2.16 times as fast as CL
    assert ctrl.takeover_heat("CH")[0] == pytest.approx(2.16 * ctrl.takeover_heat("CL")[0], rel=0.01)
    ctrl.F_cmd = 0.0
    M_pre = FLAT.launch.F_prefill_n * FLAT.CH.speed_ratio_m / eta
    assert ctrl.takeover_heat("CH") == pytest.approx((M_pre * slip_x * rpm, M_pre * 150.0 * rpm), rel=1e-9)


def test_stops_when_neither_can_take_over_but_not_before_the_hotter_is_near_its_limit():
    ctrl, clock = creeping()
    inp = replace(CREEP, clutch_in_rpm=50.0, cl_out_rpm=50.0, ch_out_rpm=50.0, v_mps=0.2, P_CL_mpa=0.6)
    limit = ctrl.limit("CL", 0.0)
    # CH cannot take over: 1 K over its limit at no heat (margin_k of its own) less the headroom
    hot_CH = FLAT.strategy.T_safe_c - ctrl.margin_k("CH") - FLAT.strategy.takeover_headroom_k + 1.0
    out = hold_at(ctrl, clock, inp, FLAT.strategy.T_safe_c - 15.0, hot_CH)
    assert out.state == "CREEP" and not out.brake_request  # 15 K under T_safe: keeps creeping on CL
    P0 = out.P_CL_cmd_mpa
    out = hold_at(ctrl, clock, inp, limit + 0.01, hot_CH)
    assert out.state == "STOPPED_OVERHEAT" and out.brake_request and out.active_clutch == "NONE"
    out = run(ctrl, clock, inp, FLAT.strategy.stop_release_s / 2)
    assert 0.0 < out.P_CL_cmd_mpa < P0  # torque ramps out while the brake comes in
    out = run(ctrl, clock, inp, FLAT.strategy.stop_release_s)
    assert out.P_CL_cmd_mpa == out.P_CH_cmd_mpa == 0.0 and out.brake_request
    out = run(ctrl, clock, inp, 5.0)  # latched while the driver keeps asking
    assert out.state == "STOPPED_OVERHEAT"
    out = ctrl.update(replace(inp, creep_request=False), clock.tick())
    assert out.state == "IDLE"


def test_startup_estimates_plates_from_the_oil_and_waits_before_creeping():
    ctrl, clock = CreepController(FLAT), Clock()
    hot = replace(BRAKED, T_oil_CL_c=200.0, T_oil_CH_c=120.0, T_sump_c=90.0)
    out = ctrl.update(hot, clock.tick())
    c = FLAT.CL
    assert out.T_CL_pred_c == pytest.approx(200.0 + c.cooling_w_k / c.K_plate_oil_w_k * 110.0)
    assert out.T_CH_pred_c == pytest.approx(120.0 + FLAT.CH.cooling_w_k / FLAT.CH.K_plate_oil_w_k * 30.0)
    window = FLAT.strategy.startup_observer_s
    out = run(ctrl, clock, replace(hot, creep_request=True, brake_pct=0.0), window - 2 * DT)
    assert out.state == "IDLE" and out.brake_request and out.P_CL_cmd_mpa == 0.0  # held, not creeping yet
    out = run(ctrl, clock, replace(hot, creep_request=True, brake_pct=0.0), 3 * DT)
    assert out.state == "ENGAGE" and out.brake_request and out.P_CL_cmd_mpa > 0.0
    T = out.T_CL_pred_c  # from now on the predictor: the estimate cools towards the oil with tau = C / K
    tau = c.C_plate_j_k / c.K_plate_oil_w_k
    ctrl2, clock2 = CreepController(FLAT), Clock()
    run(ctrl2, clock2, hot, window + DT)
    T0 = ctrl2.T_pred["CL"]
    out = run(ctrl2, clock2, hot, tau)
    assert out.T_CL_pred_c == pytest.approx(200.0 + (T0 - 200.0) / math.e, abs=0.05) and T > 200.0


def test_startup_refuses_to_creep_when_both_plates_are_too_hot():
    ctrl, clock = CreepController(FLAT), Clock()
    hot = replace(CREEP, T_oil_CL_c=240.0, T_oil_CH_c=238.0, T_sump_c=150.0)
    out = run(ctrl, clock, hot, FLAT.strategy.startup_observer_s + 0.05)
    assert out.state == "STOPPED_OVERHEAT" and out.brake_request and out.P_CL_cmd_mpa == 0.0


def test_missing_plant_frames_open_both_clutches():
    ctrl, clock = creeping()
    out = ctrl.update(TcuInputs(plant_valid=False), clock.tick())
    assert out.state == "FAULT" and out.fault_bits & 0x01 and out.P_CL_cmd_mpa == out.P_CH_cmd_mpa == 0.0
    out = ctrl.update(replace(CREEP, creep_request=False, v_mps=0.2), clock.tick())
    assert out.state == "IDLE" and out.fault_bits == 0


def test_time_must_advance():
    ctrl = CreepController(FLAT)
    ctrl.update(CREEP, 1.0)
    with pytest.raises(ValueError):
        ctrl.update(CREEP, 1.0)


def test_friction_map_and_plate_step_by_hand():
    m = FrictionMap((100.0, 200.0), (0.0, 100.0), (0.0, 1.0),
                    (((0.06, 0.05), (0.08, 0.07)), ((0.07, 0.06), (0.10, 0.09))))  # [T][slip][P]
    assert friction_coefficient(m, 150.0, 50.0, 0.0) == pytest.approx((0.06 + 0.08 + 0.07 + 0.10) / 4)
    assert friction_coefficient(m, 150.0, 50.0, 0.5) == pytest.approx((0.06 + 0.08 + 0.07 + 0.10) / 4 - 0.005)
    assert friction_coefficient(m, 300.0, -500.0, 2.0) == pytest.approx(0.09)  # clamped, |slip|
    assert friction_coefficient(m, 100.0, 0.0, 0.25) == pytest.approx(0.0575)
    c = CAL.CL
    Q = friction_heat(m, c, 100.0, 100.0, 0.5)
    assert Q == pytest.approx(0.075 * c.k_geom_m3 * 0.5e6 * 100.0 * 2 * math.pi / 60)
    T = 100.0
    for _ in range(200):
        T = plate_step(c, T, Q, 90.0, 1.0)
    assert T == pytest.approx(90.0 + Q / c.K_plate_oil_w_k, rel=1e-6)
    tau = c.C_plate_j_k / c.K_plate_oil_w_k
    assert plate_step(c, 100.0, 0.0, 90.0, tau) == pytest.approx(90.0 + 10.0 / math.e)


def test_pid_anti_windup_rate_limit_and_bad_dt():
    pid = PID(kp=1.0, ki=10.0, out_min=0.0, out_max=1.0, rate_limit=1.0)
    pid.reset(0.0)
    outs = [pid.update(5.0, 0.1) for _ in range(50)]
    assert outs[0] == pytest.approx(0.1) and max(outs) == 1.0  # rate-limited rise to the limit
    assert pid.integral <= 1.0  # no wind-up while saturated
    assert pid.update(-0.5, 0.1) < 1.0  # comes off the limit at once when the error turns
    with pytest.raises(ValueError):
        pid.update(1.0, 0.0)


def test_over_its_target_the_speed_control_asks_the_brakes_to_decelerate_and_the_full_brake_is_a_backstop():
    """Downhill (0.3 m/s against 0.2, both clutches open and slipping forwards): the PI's wheel force goes negative
    and its negative part is a deceleration of the nominal mass asked of the brakes. By hand: e = -0.1 m/s,
    kp e = -8,000 N at once, the integral -16,000 N/s more, so within 1 s it reaches the limit
    -m_kg decel_max = -7,840 x 2 = -15,680 N: 2.0 m/s^2 asked, the clutches at zero, no full brake while the
    vehicle does not speed up. Speeding up at that limit (brakes that do not follow it), the full brake."""
    ctrl, clock = creeping()
    s = FLAT.speed
    over = replace(CREEP, v_mps=0.3, P_CL_mpa=0.0, P_CH_mpa=0.0)
    out = ctrl.update(over, clock.tick())
    assert out.decel_request_mps2 == 0.0 or out.P_CL_cmd_mpa == 0.0  # never the clutch and the brakes at once
    out = run(ctrl, clock, over, 1.0)
    limit, step = -FLAT.vehicle.m_kg * s.decel_max_mps2, s.ki_n_per_m * 0.1 * DT  # (integrated to within a step)
    assert limit <= ctrl.F_cmd <= limit + step
    assert out.decel_request_mps2 == pytest.approx(-ctrl.F_cmd / FLAT.vehicle.m_kg, rel=1e-12)
    assert out.decel_request_mps2 >= s.decel_max_mps2 - step / FLAT.vehicle.m_kg
    assert out.P_CL_cmd_mpa == out.P_CH_cmd_mpa == 0.0
    assert out.state == "CREEP" and not out.brake_request
    v = 0.3
    for _ in range(3):  # still speeding up with the brakes' deceleration at its limit: they do not hold it
        v += 0.001
        out = ctrl.update(replace(over, v_mps=v), clock.tick())
    assert out.brake_request and out.decel_request_mps2 == 0.0
    # back at its target with the brakes: the request eases (the integral unwinds), never below zero
    ctrl, clock = creeping()
    run(ctrl, clock, over, 1.0)
    out = run(ctrl, clock, replace(over, v_mps=0.2), 0.2)
    assert 0.0 < out.decel_request_mps2 < s.decel_max_mps2
    # IDLE asks nothing of the brakes' deceleration (a standing vehicle is held by BrakeRequest)
    out = run(ctrl, clock, BRAKED, 0.1)
    assert out.state == "IDLE" and out.decel_request_mps2 == 0.0


@pytest.mark.parametrize("cls", [TcuInputs, TcuOutputs, MonitorVerdict])
def test_written_out_init_takes_the_dataclass_fields(cls):
    """TcuInputs, TcuOutputs, MonitorVerdict write their __init__ out (the mypyc build compiles it): the dataclass's
    fields, in order, with their defaults, each set (a field added but not to __init__ fails here)."""
    fields = dataclasses.fields(cls)
    init = definition(cls.__init__).args  # (from the source: a compiled __init__ shows no signature)
    params = init.args[1:]
    assert [p.arg for p in params] == [f.name for f in fields]
    defaults = [dataclasses.MISSING] * (len(params) - len(init.defaults)) + [ast.literal_eval(d) for d in init.defaults]
    assert defaults == [f.default for f in fields]
    given = [distinct(f, i) for i, f in enumerate(fields)]
    obj = cls(*given)
    assert [getattr(obj, f.name) for f in fields] == given


def distinct(field: dataclasses.Field, i: int) -> object:
    """A value of the field's type (the compiled build checks them) unlike its default and any other field's."""
    kind = field.type.partition("[")[0] if isinstance(field.type, str) else field.type.__name__  # (compiled: a type)
    if kind == "bool":
        return field.default is not True
    return {"float": 1000.5 + i, "int": 1000 + i, "str": f"value {i}", "dict": {"CL": float(i)}}[kind]


def test_a_pedal_overrun_ends_with_the_launch_that_follows_it():
    """The brake request that overrules a pressed pedal not holding the vehicle (:attr:`pedal_overrun`) lasts while
    that pedal stays pressed; the driver lifting it and the creep taking over ends it. A later press that does slow
    the vehicle is his to control again (before: the latch outlived the creep and the next press of a moving
    vehicle got the full brake request)."""
    ctrl, clock = creeping()
    light = replace(CREEP, P_CL_mpa=1.0, brake_pct=6.0)
    ctrl.update(replace(light, v_mps=0.30), clock.tick())
    out = ctrl.update(replace(light, v_mps=0.31), clock.tick())  # over 1.2 x its target and speeding up
    assert out.state == "IDLE" and out.brake_request and ctrl.pedal_overrun
    out = ctrl.update(replace(CREEP, P_CL_mpa=1.0, v_mps=0.30), clock.tick())  # foot off, still moving: creep again
    assert out.state in ("ENGAGE", "CREEP") and not ctrl.pedal_overrun
    run(ctrl, clock, replace(CREEP, P_CL_mpa=1.0, v_mps=0.2), 1.0)
    firm = replace(CREEP, P_CL_mpa=1.0, brake_pct=30.0)
    ctrl.update(replace(firm, v_mps=0.19), clock.tick())
    out = ctrl.update(replace(firm, v_mps=0.18), clock.tick())  # slowing under his pedal
    assert out.state == "IDLE" and not out.brake_request


def test_the_thermal_input_speed_is_the_larger_of_the_input_and_the_engine_speed():
    ctrl, clock = creeping()
    inp = replace(CREEP, P_CL_mpa=0.6, v_mps=0.2, engine_speed_rpm=1000.0)  # 1000 / 5.3585 = 186.6 r/min
    ctrl.update(inp, clock.tick())
    assert ctrl.input_rpm(inp) == pytest.approx(1000.0 / FLAT.vehicle.input_ratio, rel=1e-12)
    assert ctrl.thermal_slip_rpm("CL") == pytest.approx(1000.0 / FLAT.vehicle.input_ratio - 50.0, rel=1e-12)
    Q = 0.07 * FLAT.CL.k_geom_m3 * 0.6e6 * (1000.0 / FLAT.vehicle.input_ratio - 50.0) * 2 * math.pi / 60
    assert ctrl.heat["CL"] == pytest.approx(Q, rel=1e-9)  # the heat at the larger slip
    assert ctrl.input_rpm(replace(inp, engine_speed_rpm=700.0)) == 150.0  # 130.6 r/min: the input speed's


def test_the_margin_budgets_the_errors_the_checks_let_through_by_hand():
    """On the flat map, CL at 0.6 MPa, 150 r/min in, 50 out (100 r/min of slip), 0.2 m/s: the heat's undetected
    error fraction is P_REL + P_ABS / P + dn / slip, dn = (3 % x 0.2 m/s + 0.5 mm/s) / r_CL + 1 % x 150 r/min
    + 0.1 r/min; in steady state (20 s, 13 plate time constants) the prediction's error from it is f Q / K (the
    model's own gain); after one cycle from none, f Q dt / C (the energy over the capacity). The margin adds the
    identified error, the oil sensors' accuracy, the fall check's step and the plate's rise over one oil frame at
    the largest heat seen; the oil sensors' undetected error from key-on at the highest key-on reading, 100 degC:
    the key-on check's tolerance 2 (0.3 + 0.005 x 100) + 2 x 0.05 K, one healthy sensor's 0.8 K low, the reading's
    half step, 2.55 K (more than the class's 1.55 K at T_safe). An oil fault is an offset or a gain (g T in degC):
    from key-on, 2.55 K of a key-on oil at least 100 - 0.8 degC, grown to T_safe; later, on a sensor within its
    class (1.55 K), the fall check's step, grown from the lowest reading (100 degC) to T_safe; the larger of the
    two."""
    ctrl, clock = creeping()
    inp = replace(CREEP, P_CL_mpa=0.6, v_mps=0.2)
    ctrl.heat_error_k["CL"] = 0.0
    ctrl.update(inp, clock.tick())
    rpm, s, c = 2 * math.pi / 60, FLAT.strategy, FLAT.CL
    Q = 0.07 * c.k_geom_m3 * 0.6e6 * 100.0 * rpm
    dn = (0.03 * 0.2 + 0.0005) / (c.speed_ratio_m * rpm) + 0.01 * 150.0 + 0.1
    assert ctrl.slip_error_rpm("CL", inp) == pytest.approx(dn, rel=1e-12) and 3.3 < dn < 3.5
    f = 0.05 + 0.02 / 0.6 + dn / 100.0
    assert ctrl.heat_error_fraction("CL", inp, 0.6, 100.0) == pytest.approx(f, rel=1e-12)
    assert ctrl.heat_error_k["CL"] == pytest.approx(f * Q * DT / c.C_plate_j_k, rel=1e-2)  # energy balance
    run(ctrl, clock, inp, 20.0)
    assert ctrl.heat_error_k["CL"] == pytest.approx(f * Q / c.K_plate_oil_w_k, rel=1e-4)  # steady state
    assert ctrl.heat_max["CL"] >= Q * (1.0 + f) * (1.0 - 1e-9)
    step = OIL_FALL_K + ctrl.heat_max["CL"] / c.C_plate_j_k * 0.1
    keyon, later = 2.55 / (100.0 - 0.8) * 250.0, 1.55 + step * 250.0 / 100.0
    assert 6.4 < keyon < 6.45 and 6.0 < later < 7.0
    assert ctrl.oil_margin_k("CL") == pytest.approx(max(keyon, later), rel=1e-9)
    assert ctrl.margin_k("CL") == pytest.approx(s.prediction_error_k + max(keyon, later) + f * Q / c.K_plate_oil_w_k,
                                                rel=1e-4)
    # and the monitor's and crossover's powers scaled by the same fraction, at the command's pressure
    P = max(ctrl.P_cmd["CL"], 0.6)
    assert ctrl.heat_scale("CL") == pytest.approx(1.0 + 0.05 + 0.02 / P + dn / 100.0, rel=1e-12)
