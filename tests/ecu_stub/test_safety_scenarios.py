"""The worst cases of issue 18 as short scripted closed-loop runs (plant and ecu-stub in lockstep), judged on the
plant's truth and the summary's failure metrics: a light brake drag across a CL -> CH handover decision, downhill
creep, 2 s of missing PLANT_OIL_TEMP on Table I's grade, creep-request toggles without the brake, and both clutches
used to their limits before the stop. Then the violations ``dsg-hil sweep`` found over issue 18's space, each as
its sweep run (the space's inputs) in the closed loop, expected to fail until the TCU is fixed."""

from __future__ import annotations

import pytest

from dsg_hil.physics.params import load_params, with_overrides
from dsg_hil.protocol import Codec
from dsg_hil.sim.loop import run_closed_loop
from dsg_hil.sim.run import RunConfig, open_run
from dsg_hil.sim.scenario import parse_scenario
from dsg_hil.sweep.page import HANDOVER_DRIVABLE_PCT
from dsg_hil.sweep.space import SAFETY_SPACE, load_space
from dsg_hil.sweep.verdict import LIMITS
from dsg_hil.testing import run_plant
from ecu_stub.controller import CreepController
from ecu_stub.runner import TCU_USES, TcuRunner

from .sample_runs import RUNS as SAMPLE_RUNS

T_SAFE_C = 250.0
V_CREEP = 0.206  # m/s, the default scenario's desired speed
ROLLBACK_MAX_MPS = 0.01  # drivability: at most 10 mm/s backwards at a brake release
GRADE = 0.174  # Table I


def worst_case(duration, events, grade=GRADE, idle=800.0, T_CL=100.0, T_CH=100.0, T_oil=100.0, faults=""):
    """A scenario held on the brake for 1 s, then ``events`` (t, creep, brake 0..1, speed)."""
    text = (f'name = "worst case"\nduration_s = {duration}\ngrade_rad = {grade}\nengine_speed_rpm = {idle}\n'
            f"[initial]\nT_CL_c = {T_CL}\nT_CH_c = {T_CH}\nT_clutch_c = {T_CL}\nT_oil_c = {T_oil}\nv_mps = 0.0\n")
    for t, request, brake, speed in [(0.0, False, 1.0, 0.0), *events]:
        text += (f"[[driver]]\nt_s = {t}\ncreep_request = {str(request).lower()}\nbrake = {brake}\n"
                 f"desired_speed_mps = {speed}\n")
    return parse_scenario(text + faults, "worst case")


# a clutch is used to within this of T_safe - its margin (margin_k) before a stop: the crossover's and the
# monitor's allowance for the heat until a release (about 5-7.5 K in the cases below)
USED_WITHIN_K = 10.0


def creep(duration, events, grade=GRADE, idle=800.0, T_CL=100.0, T_CH=100.0, T_oil=100.0, faults="", mass=1.0):
    """Summary of a closed-loop run of :func:`worst_case` (``mass``: a factor on the vehicle's)."""
    return creep_margin(duration, events, grade, idle, T_CL, T_CH, T_oil, faults, mass)[0]


def creep_margin(duration, events, grade=GRADE, idle=800.0, T_CL=100.0, T_CH=100.0, T_oil=100.0, faults="",
                 mass=1.0):
    """:func:`creep` and the TCU's thermal margin ``margin_k`` of each clutch at the run's end [K]."""
    params = load_params()
    if mass != 1.0:
        params = with_overrides(params, {"vehicle.m": params.vehicle.m * mass})
    return closed_loop_margin(worst_case(duration, events, grade, idle, T_CL, T_CH, T_oil, faults), params)


def closed_loop_margin(scenario, params):
    """(summary, the bundled TCU's ``margin_k`` of each clutch at the end [K]) of a closed-loop run."""
    tcus: list[TcuRunner] = []

    def factory(db, bus):
        tcus.append(TcuRunner(Codec(db, TCU_USES), bus))
        return tcus[0]
    run = run_closed_loop(scenario, params, tcu_factory=factory)
    controller = tcus[0].controller
    assert isinstance(controller, CreepController)
    return run.summary, {c: controller.margin_k(c) for c in ("CL", "CH")}


def test_light_brake_drag_across_a_handover_decision_keeps_the_true_plate_under_t_safe():
    """In range (level road, mass -30 %, oil 130 degC, idle 1300 r/min), the driver's foot resting at 4.7 %
    (read as 4.5 %, under the 5 % 'pressed' threshold) from 0.3 s before the TCU decides to hand CL over: before
    the monitor, CL's true plate reached 251.1 degC in this case (starting from 100 degC, decision at 55.9 s)."""
    hot = {"grade": 0.0, "idle": 1300.0, "T_CL": 238.0, "T_oil": 130.0, "mass": 0.7}
    plain = creep(10.0, [(1.0, True, 0.0, V_CREEP)], **hot)
    assert plain["handovers"] and plain["handovers"][0]["from"] == "CL"
    t_decision = plain["handovers"][0]["t_s"] - 0.1  # TCU_STATUS every 100 ms: decided within the period before
    dragged, margin = creep_margin(t_decision + 4.0, [(1.0, True, 0.0, V_CREEP),
                                                      (round(t_decision - 0.3, 2), True, 0.047, V_CREEP)], **hot)
    assert dragged["max_plate_temp_c"]["CL"] <= T_SAFE_C and dragged["time_above_limit_s"]["CL"] == 0.0
    assert dragged["min_margin_c"]["truth"] >= 0.0
    # CL was used to its limit, not given up early (>= 240 degC before the margin budgeted an oil gain's growth)
    assert dragged["max_plate_temp_c"]["CL"] >= T_SAFE_C - margin["CL"] - USED_WITHIN_K
    # the monitor released CL faster than its share: CH takes the rest, so the vehicle, braked by the drag, is not
    # driven to an overshoot by a wound-up integral (before: 0.302 m/s, +46 %; now 0.231 m/s)
    assert dragged["max_speed_creep_mps"] <= 1.2 * V_CREEP
    # the speed through the handover: the plain run's, with no pedal in its window, counts in the unbraked part too;
    # a 2 % drag from 0.2 s after the decision slows the vehicle by a fifth (not judged with the drag above, begun
    # before the handover: the speed then is out of the band) and counts only in the whole (the runner tells the
    # summary the driver's pedal)
    assert plain["handover_deviation_unbraked_pct"] == plain["handover_deviation_pct"] is not None
    late = creep(t_decision + 3.0, [(1.0, True, 0.0, V_CREEP), (round(t_decision + 0.2, 2), True, 0.02, V_CREEP)],
                 **hot)
    assert late["handover_deviation_pct"] > HANDOVER_DRIVABLE_PCT and late["handover_deviation_unbraked_pct"] is None


def test_downhill_creep_does_not_run_away():
    """-0.15 rad with 0.206 m/s requested: before, 13.6 m/s (no clutch can brake at creep speed)."""
    s = creep(12.0, [(1.0, True, 0.0, V_CREEP)], grade=-0.15)
    assert s["max_speed_creep_mps"] <= 1.2 * V_CREEP and s["overspeed_mps"] <= 0.2 * V_CREEP
    # no roll-back beyond a brake release's (the plant holds a standing vehicle only by its brake and the
    # breakaway resistance: the driveline's wind-up may move it back a fraction of a millimetre)
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_guarded_m"] <= 0.005


def test_missing_oil_temperature_holds_the_vehicle_on_the_grade():
    """2 s without PLANT_OIL_TEMP on Table I's grade: FAULT requests the brake (before: 0.82 m of roll-back)."""
    fault = '[[fault]]\nkind = "drop"\ntarget = "PLANT_OIL_TEMP"\nstart_s = 5.0\nend_s = 7.0\n'
    s = creep(12.0, [(1.0, True, 0.0, V_CREEP)], faults=fault)
    assert s["fault_time_s"] >= 1.5
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_guarded_m"] <= 0.005
    assert s["creep_time_s"] > 5.0  # creeping again after the fault


def test_creep_request_toggles_without_the_brake_do_not_roll_back():
    """The request withdrawn and given again every 1.5 s, the brake pedal never pressed, on Table I's grade:
    the TCU holds the vehicle whenever nobody else does (before: 19.7 m of roll-back over 20 toggles)."""
    events = [e for k in range(6) for e in ((1.0 + 3.0 * k, True, 0.0, V_CREEP), (2.5 + 3.0 * k, False, 0.0, 0.0))]
    s = creep(19.0, events)
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_m"] <= 0.005
    assert s["max_speed_creep_mps"] <= 1.2 * V_CREEP


@pytest.mark.parametrize("T_CH, handover", [(230.0, True), (247.0, False)])
def test_both_clutches_are_used_to_235_degc_before_the_stop(T_CH, handover):
    """Both plates start hot (CL 228 degC, oil 130 degC): the TCU creeps on each in turn to its handover limit and
    stops (brake) only when neither can take over, each plate having reached >= 235 degC, none 250. With CH at
    247 degC, CH is not taken: carrying the creep force it would make 16 kW (measured on the plant after such a
    handover: 16.4 kW), not CL's 7.4 kW, and its limit at that power leaves it less than ``takeover_headroom_k``
    (the gate before it took CL's power and handed over). Where that starts moves with the calibration's
    ``prediction_error_k``: at 3.5 K CH was not taken from 245 degC, at 2.5 K (re-identified) from 246 degC; the
    cases here (230 and 247 degC) are either side at 2 K too (the tests pass)."""
    s = creep(40.0 if handover else 10.0, [(1.0, True, 0.0, V_CREEP)], T_CL=228.0, T_CH=T_CH, T_oil=130.0)
    assert s["stop_reason"] == "STOPPED_OVERHEAT" and bool(s["handovers"]) == handover
    assert 235.0 <= min(s["max_plate_temp_c"].values()) and max(s["max_plate_temp_c"].values()) <= T_SAFE_C
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_guarded_m"] <= 0.005


def sweep_run(inputs):
    """Summary of a run of the shipped safety space with ``inputs`` (the settings not given: the generators')."""
    task = load_space(SAFETY_SPACE).task(0, inputs)
    return run_plant(scenario=parse_scenario(task["scenario"], task["run_id"]), params=task["params"],
                     faults=task["faults"], log=None).summary


def sweep_run_margin(inputs):
    """:func:`sweep_run` in one process with the bundled TCU: (summary, the TCU's thermal margin ``margin_k`` of each
    clutch at the run's end [K]: the errors it budgets, docs/safety.md)."""
    task = load_space(SAFETY_SPACE).task(0, inputs)
    assert not task["faults"]
    return closed_loop_margin(parse_scenario(task["scenario"], task["run_id"]),
                              with_overrides(load_params(), task["params"]))


@pytest.mark.slow
def test_sweep_found_creep_toggles_without_the_brake_on_a_steep_grade_keep_the_vehicle_from_rolling_back():
    """Creep-request toggles without the brake on a 0.18 rad grade (found by dsg-hil sweep --search, no frame
    faults, trial 51): 53 mm of roll-back in 240 s (limit 50 mm), nearly all of it a phantom: a vehicle held by its
    brake rang at the 1-ms step's Nyquist frequency and the summary counted the backward half-samples. With the
    plant ending a held vehicle's step at rest and roll-back counted as displacement: about 1 mm."""
    s = sweep_run({"grade_rad": 0.17873974990560423, "engine_speed_rpm": 1516.7114762698552,
                   "initial.T_clutch_c": 145.19316607307553, "initial.T_oil_c": 104.89154397833468,
                   "params.vehicle.m": 5471.009031639687, "driver.behaviour": "creep_toggles",
                   "driver.desired_speed_mps": 0.11029789551699393, "driver.toggle_s": 6.178608904673,
                   "driver.toggle_brake": False, "driver.drag_level": 0.01234188598147299,
                   "driver.drag_onset_s": 152.284491910042, "driver.drag_duration_s": 99.39937099048518})
    assert s["rollback_m"] <= LIMITS["rollback_m"]


@pytest.mark.slow
def test_sweep_found_a_stuck_zero_vehicle_speed_does_not_drive_the_vehicle_to_overspeed():
    """PLANT_VEHICLE.VehicleSpeed stuck at 0 (CRC and counter valid) for 3.1 s while creeping downhill (found by
    dsg-hil sweep safety.toml --n 200, run r00031): before the plausibility vote (ecu_stub/plausibility.py) the TCU
    believed the vehicle stopped and drove it to 0.97 m/s with 0.37 m/s requested; now the clutch outputs' speed
    replaces VehicleSpeed once 40 mm lie between them (0.11 s)."""
    v_desired = 0.37226325862838405
    s = sweep_run({"duration_s": 115.0, "grade_rad": -0.08673544924571712, "engine_speed_rpm": 1302.86417634572,
                   "initial.T_clutch_c": 53.139048574549534, "initial.T_oil_c": 105.76007244548532,
                   "params.vehicle.m": 9650.764535318314, "driver.behaviour": "speed_changes",
                   "driver.desired_speed_mps": v_desired, "driver.speed_2_mps": 0.12846612416353098,
                   "driver.change_s": 47.673945821744645, "fault": "stuck:PLANT_VEHICLE.VehicleSpeed,value=0",
                   "fault_at_s": 107.69056724001449, "fault_duration_s": 3.125929724799683})
    assert s["max_speed_creep_mps"] <= v_desired + LIMITS["overspeed_mps"]


@pytest.mark.slow
def test_sweep_found_a_stuck_zero_vehicle_speed_on_a_light_vehicle_does_not_overspeed_before_the_vote():
    """VehicleSpeed stuck at 0 for 3.8 s, a light vehicle (5,086 kg) creeping at 0.187 m/s on 0.1 rad (found by a
    1,000-run sample of the shipped space, r00450): in the 0.15 s the vote needs for its 40 mm the speed controller,
    believing the vehicle stopped, tripled the clutch force and the vehicle reached 0.759 m/s (limit 0.687). The
    step from 0.187 to 0 in 10 ms is more than any unbraked vehicle decelerates: VehicleSpeed is replaced at once."""
    v_desired = 0.18711234556882245
    s = sweep_run({"duration_s": 190.0, "grade_rad": 0.0998097309533181, "engine_speed_rpm": 1427.790491740583,
                   "initial.T_clutch_c": 132.20533198056106, "initial.T_oil_c": 47.306774924715334,
                   "params.vehicle.m": 5085.786447787408, "driver.behaviour": "creep",
                   "driver.desired_speed_mps": v_desired, "driver.drag_level": 0.08374774995500195,
                   "driver.drag_onset_s": 39.55447684288723, "driver.drag_duration_s": 32.53762385554489,
                   "fault": "stuck:PLANT_VEHICLE.VehicleSpeed,value=0", "fault_at_s": 183.66457105057896,
                   "fault_duration_s": 3.7808555261842134})
    assert s["faults"]["injected"]  # the fault was in the run
    assert s["max_speed_creep_mps"] <= v_desired + LIMITS["overspeed_mps"]
    assert s["max_speed_creep_mps"] <= 1.2 * v_desired  # drivability: within the +-20 % band through the fault


@pytest.mark.slow
def test_search_found_a_stuck_zero_vehicle_speed_under_a_light_brake_drag_is_replaced_at_the_step():
    """VehicleSpeed stuck at 0 for 0.21 s while the driver's foot rests on the pedal at 0.6 % (found by the 500-trial
    search, s00080): with any pedal counted as braking the step was left to the vote, and the vehicle reached
    0.548 m/s with 0.164 requested (limit 0.664). A 0.6 % pedal adds at most 0.32 m/s^2 of deceleration (the
    calibration's 52.7 m/s^2 per full pedal): the step from 0.164 m/s to 0 is still impossible, replaced at once."""
    v_desired = 0.16355901458288008
    s = sweep_run({"duration_s": 140.0, "grade_rad": -0.006186201872076885, "engine_speed_rpm": 1324.493735712738,
                   "initial.T_clutch_c": 107.62612611166509, "initial.T_oil_c": 71.41128597311791,
                   "params.vehicle.m": 7861.743891171063, "driver.behaviour": "speed_changes",
                   "driver.desired_speed_mps": 0.10398612359686751, "driver.speed_2_mps": v_desired,
                   "driver.change_s": 17.641925402426097, "driver.drag_level": 0.006139825890862938,
                   "driver.drag_onset_s": 129.13404440937413, "driver.drag_duration_s": 80.70568058441455,
                   "fault": "stuck:PLANT_VEHICLE.VehicleSpeed,value=0", "fault_at_s": 135.4425280470662,
                   "fault_duration_s": 0.21481900970048745})
    assert s["faults"]["injected"]
    assert s["max_speed_creep_mps"] <= 1.2 * v_desired  # before: 0.548 m/s


@pytest.mark.slow
def test_sample_found_a_clutch_that_cannot_carry_the_vehicle_stops_it_rather_than_stall_under_creep():
    """11.0 t on 0.175 rad at 1,486 r/min, creep requested (found by the 5,000-run sample of the shipped space,
    r00468): CL reached its limit after 13 s and handed over to CH, whose gear needs 1.73 times CL's torque; at its
    pressure limit CH slowed the vehicle to 9 mm/s and held it there, heating at 7.5 K/s, until the driver withdrew
    the request (the sweep's standstill: creep requested, vehicle at rest, no stop). CL too hot, CH too weak: the
    TCU stops (brake held) once the force has stayed at CH's capacity with the vehicle under half its target."""
    s, margin = sweep_run_margin({
        "duration_s": 20.0, "grade_rad": 0.17519253268197146, "engine_speed_rpm": 1486.4046314130019,
        "initial.T_clutch_c": 52.37771165391007, "initial.T_oil_c": 87.79366488680176,
        "params.vehicle.m": 11037.077433300437, "driver.behaviour": "creep_toggles",
        "driver.desired_speed_mps": 0.28723038538861795, "driver.toggle_s": 19.358877229205213,
        "driver.toggle_brake": False, "driver.drag_level": 0.051262641830609273,
        "driver.drag_onset_s": 47.31397985738239, "driver.drag_duration_s": 142.37711020942905
    })
    # since CARRY_MARGIN, CH (its modelled capacity within 10 % of the force) is not handed the vehicle at all: CL
    # carries on to the monitor's stop
    assert s["handovers"] == []
    assert s["stop_reason"] == "STOPPED_OVERHEAT"  # before: vehicle_stopped at 17.1 s, creep requested
    assert s["tcu_stop_time_s"] <= 17.1  # before the vehicle came to rest under the creep request
    # CL used to its limit first (not giving up early): >= 235 degC before the margin budgeted the sensor errors the
    # checks let through (docs/safety.md), 234.1 degC since, 221.4 degC since it budgets an oil gain's growth (the
    # oil cold in a heavy launch: a step hidden in a frame's rise, grown to T_safe; 22 K of margin here)
    assert s["max_plate_temp_c"]["CL"] >= T_SAFE_C - margin["CL"] - USED_WITHIN_K
    assert s["max_plate_temp_c"]["CL"] <= T_SAFE_C and s["rollback_guarded_m"] <= LIMITS["rollback_m"]


def test_sample_found_a_clutch_whose_partner_cannot_carry_is_used_to_the_monitors_stop_not_given_up_early():
    """10.3 t on 0.246 rad at 1,746 r/min, 0.344 m/s requested (found by the 5,000-run sample on d146527, r00071):
    CL's handover limit at this power is low (the crossover's heat allowance, about 17 K), CH could not give the
    33 kN, and the TCU stopped at CL's handover limit with the hotter plate at 233.5 degC (issue 18: used to >= 235
    degC before a stop). With no handover possible the allowance is moot: CL carries on until the monitor stops."""
    s, margin = sweep_run_margin({
        "duration_s": 25.0, "grade_rad": 0.24610819144805687, "engine_speed_rpm": 1745.994521005034,
        "initial.T_clutch_c": 41.21347795847542, "params.vehicle.m": 10254.863273226438,
        "driver.behaviour": "creep", "driver.desired_speed_mps": 0.34408601910639397
    })
    assert s["handovers"] == [] and s["stop_reason"] == "STOPPED_OVERHEAT"
    # before: 233.54 degC, the handover limit (its allowance about 17 K); 218.4 degC since the margin budgets an oil
    # gain's growth (26 K here: a 52-kW launch from 48 degC)
    assert T_SAFE_C - margin["CL"] - USED_WITHIN_K <= s["max_plate_temp_c"]["CL"] <= T_SAFE_C
    assert s["rollback_guarded_m"] <= LIMITS["rollback_m"]


@pytest.mark.slow
def test_sample_found_withdrawing_creep_after_an_overheat_stop_keeps_the_vehicle_held():
    """Creep-request toggles without the brake, 5.0 t on 0.234 rad, stopped for overheat at 46.7 s (found by the
    5,000-run sample, r01017): leaving STOPPED_OVERHEAT for IDLE the TCU cleared its brake request for one cycle
    (IDLE sets it again the next); when TCU_STATUS was due in that cycle the plant had no brake for 100 ms and the
    vehicle rolled back at 95 mm/s. IDLE holds the vehicle from its first cycle."""
    s = sweep_run({"grade_rad": 0.23404840022804244, "engine_speed_rpm": 1823.1654226933797,
                   "initial.T_clutch_c": 134.76339876078418, "initial.T_oil_c": 135.39255433656524,
                   "params.vehicle.m": 4986.114192342171, "driver.behaviour": "creep_toggles",
                   "driver.desired_speed_mps": 0.10453544926761907, "driver.toggle_s": 19.108611831864515,
                   "driver.toggle_brake": False, "driver.drag_level": 0.030971739677655083,
                   "driver.drag_onset_s": 0.08657669862627064, "driver.drag_duration_s": 179.93374127459654})
    assert s["tcu_stop_time_s"] is not None  # the overheat stop and the request withdrawn after it were in the run
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS  # before: -0.0949 m/s at 211.3 s


@pytest.mark.slow
def test_sweep_found_a_slow_creep_with_a_light_drag_on_a_steep_grade_does_not_roll_back():
    """Creeping at 0.068 m/s on a 0.22 rad grade with a 3.4 % brake drag from 160 s (found by dsg-hil sweep --search
    over brake drags, no frame faults, trial 82): 53 mm of roll-back while creep was requested (limit 50 mm; 48.3 mm
    on another machine's run of the same code: the held vehicle's Nyquist ringing, sampled every 10 ms, made the
    figure depend on its phase). With the plant ending a held vehicle's step at rest: about 1 mm."""
    s = sweep_run({"grade_rad": 0.22236134016833697, "engine_speed_rpm": 1158.3363783410448,
                   "initial.T_clutch_c": 129.9920363924616, "initial.T_oil_c": 57.05228801052779,
                   "params.vehicle.m": 8228.65051447917, "driver.behaviour": "brake_drag",
                   "driver.desired_speed_mps": 0.06772472789428888, "driver.drag_level": 0.03431518347737088,
                   "driver.drag_onset_s": 159.58598194771338, "driver.drag_duration_s": 102.298512977253})
    assert s["rollback_guarded_m"] <= LIMITS["rollback_m"]


def _frame_fault(kind: str, start: float, end: float) -> str:
    return f'[[fault]]\nkind = "{kind}"\ntarget = "TCU_CMD"\nstart_s = {start}\nend_s = {end}\n'


@pytest.mark.slow
@pytest.mark.parametrize("kind, seconds, grade, before_m", [("drop", 2.0, GRADE, 0.843),
                                                             ("corrupt_crc", 3.0, GRADE, 2.083),
                                                             ("freeze_counter", 5.0, 0.243, 0.117)])
def test_lost_commands_do_not_roll_the_vehicle_back(kind, seconds, grade, before_m):
    """The TCU's commands lost on the bus (the sweep's 10 TCU_CMD-fault violations of 200): the gearbox releases
    both clutches after 30 ms and, before, nobody braked: 0.843 m (2 s dropped) and 2.083 m (3 s corrupted) of
    roll-back on Table I's grade. The TCU sees its pressures not following its commands (the pressure check) and
    the vehicle rolling back, and requests the brake while they stay implausible. Held so, it launches again as
    from rest (pre-fill under the brake, released once the measured pressure has built up): before, it released
    the brake once the check healed with the commands still lost, and on a 0.243-rad grade rolled back twice more
    (0.117 m in all for 5 s of frozen counters, now 0.014 m)."""
    s = creep(7.0 + max(seconds, 5.0) + 4.0, [(1.0, True, 0.0, V_CREEP)], grade=grade,
              faults=_frame_fault(kind, 5.0, 5.0 + seconds))
    assert s["rollback_m"] <= LIMITS["rollback_m"] < before_m
    assert s["creep_time_s"] > 4.0  # creeping again after the fault


def test_lost_commands_on_the_level_do_not_wind_the_speed_controller_up():
    """5 s of frozen TCU_CMD counters on the level: the vehicle coasts to rest while the speed controller's force
    reaches no clutch. Before, its integral wound up meanwhile and the creep overshot to 0.351 m/s (+70 %) when
    the commands came back; now it is held while the pressures are implausible and the standing vehicle is held
    and launched again as from rest: a launch's overshoot (at most +20 %, the drivability band)."""
    s = creep(14.0, [(1.0, True, 0.0, V_CREEP)], grade=0.0, faults=_frame_fault("freeze_counter", 5.0, 10.0))
    assert s["max_speed_creep_mps"] <= 1.2 * V_CREEP and s["creep_time_s"] > 4.0


def test_a_pressure_sensor_stuck_at_zero_on_a_working_clutch_is_not_braked_against():
    """The same pressure check with the clutch working (only the sensor reads 0): the vehicle moves as commanded,
    so no brake fights the clutch and the creep goes on as without the fault."""
    stuck = '[[fault]]\nkind = "stuck"\ntarget = "PLANT_PRESSURE.P_CL"\nvalue = 0.0\nstart_s = 2.0\nend_s = 12.0\n'
    s, plain = (creep(12.0, [(1.0, True, 0.0, V_CREEP)], faults=f) for f in (stuck, ""))
    assert s["creep_time_s"] == pytest.approx(plain["creep_time_s"], abs=0.05)
    assert s["rollback_m"] <= 0.005


def _search_stop_and_go():
    """The falsification search's first counterexample, 60 s of it: a vehicle +34 % on 0.211 rad at 962 r/min, creep
    and brake in turn every 5.7 s."""
    events, t = [], 1.0
    while t < 60.0:
        events += [(t, True, 0.0, 0.3055), (t + 5.731, False, 1.0, 0.0)]
        t += 11.462
    return creep(60.0, events, grade=0.211, idle=962.0, mass=10544.16 / 7840.0)


@pytest.mark.slow
def test_stop_and_go_beyond_the_prefill_s_design_does_not_roll_back_at_the_brake_releases():
    """The fixed pre-fill (sized for +30 % on 0.2 rad) let the vehicle roll back at every brake release, up to
    13.5 mm/s here (51 mm over the search's 240 s); the pre-fill for the grade read at the standstill
    (CreepController.prefill_force) holds it."""
    s = _search_stop_and_go()
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_m"] <= 0.005


@pytest.mark.slow
def test_stop_and_go_beyond_the_prefill_s_design_keeps_the_speed_within_20_percent_through_its_handover():
    """The same run's CL -> CH handover at 36.7 s, CL at 243 degC: through the crossover the thermal monitor
    released CL faster than its share (its bound), and the on-coming CH took only its planned share, so the wheel
    force fell to 28-29 kN against 31-46 kN commanded (34 kN road load): the vehicle dipped to 0.193 m/s, the
    integral wound up to 46 kN and the vehicle overshot to 0.436 m/s (+43 %; +19.6 % on 387ed20, whose slightly
    slower launch moved the decision). The on-coming clutch now takes the force the off-going one no longer gives:
    0.302-0.326 m/s through the crossover, 0.356 m/s at its end. Since CH must also carry with CARRY_MARGIN to
    spare, this handover is not made at all (CL carries on to the monitor's stop): the speed band holds either way."""
    s = _search_stop_and_go()
    assert (s["handover_deviation_pct"] or 0.0) <= 20.0 and s["max_speed_creep_mps"] <= 1.2 * 0.3055
    assert max(s["max_plate_temp_c"].values()) <= T_SAFE_C


@pytest.mark.parametrize("mass, v_desired", [(1.5, 0.05), (1.5, 0.4), (0.5, 0.05), (0.5, 0.4)])
def test_a_first_launch_on_the_steepest_grade_neither_rolls_back_nor_surges(mass, v_desired):
    """The first launch (nothing learned) of the heaviest and the lightest vehicle of the swept range on its steepest
    grade, 0.25 rad. Before the accelerometer (PLANT_VEHICLE.LongAccel), the fixed pre-fill (sized for +30 % on
    0.2 rad) let the heaviest roll back at up to 29.4 mm/s after the brake release; the pre-fill now holds the
    heaviest vehicle on the grade read at the standstill (CreepController.prefill_force), and the lightest is not
    pushed off beyond the drivability band."""
    s = creep(6.0, [(1.0, True, 0.0, v_desired)], grade=0.25, mass=mass)
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_m"] <= 0.005
    assert s["max_speed_creep_mps"] <= 1.2 * v_desired


def test_sample_found_stop_and_go_on_a_steep_grade_without_a_settled_creep_does_not_roll_back():
    """9.4 t on 0.236 rad, the creep request toggled with the brake every 2.8 s at 0.055 m/s (found by the 5,000-run
    sample on 387ed20, r02259): each launch rolled back about 3 mm at up to 28 mm/s (the fixed pre-fill, 7,850 N,
    against the 10.6 kN this vehicle needs), and no creep settled within 5 % of its target, so nothing was learned:
    0.132 m over 240 s (limit 0.05 m). The pre-fill for the grade read at the standstill holds it."""
    s = sweep_run({"duration_s": 30.0, "grade_rad": 0.23611792668860657, "engine_speed_rpm": 1338.6009910478228,
                   "initial.T_clutch_c": 144.84956110158873, "initial.T_oil_c": 128.65322526965258,
                   "params.vehicle.m": 9445.737207422908, "driver.behaviour": "creep_toggles",
                   "driver.desired_speed_mps": 0.054941358559715534, "driver.toggle_s": 2.831129949057855,
                   "driver.toggle_brake": True, "driver.drag_level": 0.05143490131149236,
                   "driver.drag_onset_s": 90.17787521751666, "driver.drag_duration_s": 43.737814135922484})
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_m"] <= 0.005  # before: -27.7 mm/s


R00408 = {"grade_rad": 0.2788153799516972, "engine_speed_rpm": 1726.8638942936425,
          "initial.T_clutch_c": 96.99336236450289, "initial.T_oil_c": 94.14786125297361,
          "params.vehicle.m": 10837.538926363917, "driver.behaviour": "stop_and_go",
          "driver.desired_speed_mps": 0.025455947678301376, "driver.creep_s": 37.554313213143466,
          "driver.stop_s": 14.108003720659749, "driver.drag_level": 0.019989057222812863,
          "driver.drag_onset_s": 119.17250366684364, "driver.drag_duration_s": 9.003106953395935}


@pytest.mark.slow
def test_proof_found_stop_and_go_whose_creep_never_settles_rolls_back_at_its_first_launch_only():
    """10.8 t on 0.279 rad (beyond the 0.25 rad the pre-fill reads the grade up to), stop-and-go at 0.0255 m/s (the
    safety proof sweep's batch 101, r00408, here without its frame and latent faults, which did not matter): the
    first creep stood still, then crept at 8 mm/s, and the monitor stopped CL before it reached its target, so
    nothing was learned and every launch began on the heaviest vehicle's pre-fill for 0.25 rad: 12-15 mm back each,
    0.080 m over 240 s (limit 0.05 m). The force the vehicle stood under teaches the next launch: the second launch
    (at 52.7 s) adds no roll-back (before: 14.4 mm)."""
    first = sweep_run({**R00408, "duration_s": 50.0})["rollback_m"]
    second = sweep_run({**R00408, "duration_s": 70.0})["rollback_m"]
    assert 0.0 < first and second - first <= 0.001


@pytest.mark.slow
def test_sample_found_withdrawing_creep_without_the_brake_on_a_steep_grade_ramps_the_clutch_out():
    """5.4 t creeping at 0.055 m/s on 0.24 rad, the request withdrawn without the brake (found by the 5,000-run sample
    on 387ed20, r02487): IDLE opened the clutch at once and the brake request reached the brakes with the next
    TCU_STATUS, up to 100 ms later: the vehicle stopped and rolled back at 14.9 mm/s meanwhile. The clutch now ramps
    out over ``stop_release_s``, as at an overheat stop."""
    s = sweep_run({"duration_s": 83.0, "grade_rad": 0.23977303820551457, "engine_speed_rpm": 715.7699645921265,
                   "initial.T_clutch_c": 136.83465672779528, "initial.T_oil_c": 43.5107568068505,
                   "params.vehicle.m": 5406.83915610929, "driver.behaviour": "creep_toggles",
                   "driver.desired_speed_mps": 0.05511288317634971, "driver.toggle_s": 26.57053902473213,
                   "driver.toggle_brake": False, "driver.drag_level": 0.004470466201543827,
                   "driver.drag_onset_s": 12.89070272352025, "driver.drag_duration_s": 113.13809136205803})
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS  # before: -14.9 mm/s at 80.8 s


def test_sample_found_a_monitor_stop_ramps_the_carrying_clutch_out_while_the_brake_comes_in():
    """11.4 t on 0.217 rad at 1,313 r/min (found by the 5,000-run sample on 387ed20, r02429): CH cannot carry this
    vehicle, so CL carried on to the thermal monitor's stop at 8.6 s; the monitor limited CL to zero (its measured
    pressure alone passed the bound) and the vehicle rolled back at 11.8 mm/s until the brake request arrived. The
    last cycle's bound covered a ramp out from CL's pressure (the monitor's release time): CL ramps out from there,
    and its true plate stays under T_safe."""
    s, margin = sweep_run_margin({
        "duration_s": 10.0, "grade_rad": 0.2173161195629991, "engine_speed_rpm": 1312.6709870121167,
        "initial.T_clutch_c": 106.66386279423396, "initial.T_oil_c": 74.24440042503818,
        "params.vehicle.m": 11435.443055083473, "driver.behaviour": "speed_changes",
        "driver.desired_speed_mps": 0.06401120822173016, "driver.speed_2_mps": 0.20450472768118222,
        "driver.change_s": 17.206233897063274, "driver.drag_level": 0.04206448351398612,
        "driver.drag_onset_s": 146.70062291890727, "driver.drag_duration_s": 181.6071015444852
    })
    assert s["stop_reason"] == "STOPPED_OVERHEAT" and s["handovers"] == []
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS  # before: -11.8 mm/s at 8.7 s
    # (235 degC before the margin budgeted the sensor errors the checks let through, docs/safety.md)
    assert T_SAFE_C - margin["CL"] - USED_WITHIN_K <= s["max_plate_temp_c"]["CL"] <= T_SAFE_C
    assert s["time_above_limit_s"]["CL"] == 0.0


def test_sample_found_a_partner_at_its_capacity_is_not_handed_the_vehicle():
    """11.0 t on 0.22 rad at 1,775 r/min, 0.284 m/s (found by the 5,000-run sample on e407739, r00252): CL at its
    handover limit after 5.4 s was handed over to CH with the force 0.2 % under CH's modelled capacity; at 1.5 MPa CH
    gave 8 % less than the map says and the vehicle slowed from 0.28 to 0.01 m/s (handover_deviation_pct 92.6)
    before the stall rule stopped it. CH must carry with CARRY_MARGIN to spare, so CL carries on to the monitor's
    stop, the speed held."""
    s, margin = sweep_run_margin({
        "duration_s": 12.0, "grade_rad": 0.2198423841179961, "engine_speed_rpm": 1774.9569517945345,
        "initial.T_clutch_c": 121.39856965158725, "initial.T_oil_c": 51.05841232418737,
        "params.vehicle.m": 11043.488571026677, "driver.behaviour": "stop_and_go",
        "driver.desired_speed_mps": 0.2840411088274388, "driver.creep_s": 56.44340329119722,
        "driver.stop_s": 4.362994694889822
    })
    assert s["handovers"] == [] and s["stop_reason"] == "STOPPED_OVERHEAT"  # before: CL -> CH at 6.4 s
    assert s["tcu_stop_time_s"] <= 9.4  # the stop comes no later than the stall's (at 9.4 s, the vehicle at 8 mm/s)
    # (235 degC before the margin budgeted the sensor errors the checks let through, docs/safety.md)
    assert T_SAFE_C - margin["CL"] - USED_WITHIN_K <= s["max_plate_temp_c"]["CL"] <= T_SAFE_C


# the 5,000-run sample's slowest, steepest handovers to a cool CH (sample_runs.RUNS), up to 2 s after it
SLOW_STEEP_HANDOVERS = {"r03843": 23.0, "r00652": 25.0}  # their duration [s] (the handover at 18.8 s, 21.2 s)


@pytest.mark.parametrize("run", sorted(SLOW_STEEP_HANDOVERS))
def test_sample_found_a_slow_steep_handover_to_a_cool_ch_keeps_the_speed_within_20_percent(run):
    """8.0 t on 0.197 rad at 0.061 m/s (r03843) and 8.3 t on 0.184 rad at 0.086 m/s (r00652): CL at its handover
    limit hands over to a CH at 69-75 degC, which ends the crossover at 1.2-1.35 MPa and ~185 r/min of slip. The
    friction map read mu 9-12 % over the truth there (no identification run had been there), so CH gave that much
    less than commanded as it took over and the creep dipped 36.4 and 25.6 % before the integral made it up; with
    the map_ch_slow runs in the identification 12.5 and 11.0 %."""
    s = sweep_run({**SAMPLE_RUNS[run], "duration_s": SLOW_STEEP_HANDOVERS[run]})
    assert [h["from"] for h in s["handovers"]] == ["CL"]
    assert s["handover_deviation_pct"] is not None and s["handover_deviation_pct"] <= 20.0
    assert max(s["max_plate_temp_c"].values()) <= T_SAFE_C


def test_downhill_creep_holds_its_target_speed_with_the_brakes_deceleration():
    """-0.15 rad, 0.206 m/s requested: the speed control asks the brakes for the deceleration the slope needs
    (TCU_CMD.DecelRequest) and the vehicle holds its target. Before (the full brake, one bit, on at 5 % over and
    off at a standstill): a saw-tooth between 0 and 0.242 m/s, 63 brake requests in 50 s."""
    scenario = worst_case(30.0, [(1.0, True, 0.0, V_CREEP)], grade=-0.15)
    with open_run(RunConfig(scenario=scenario, truth=True)) as run:
        summary = run.run().as_json()
    truth = run.truth()
    settled = truth["v"][truth["t"] >= 10.0]
    assert abs(settled - V_CREEP).max() <= 0.05 * V_CREEP  # within 5 % of its target from 9 s after the launch
    assert summary["max_speed_creep_mps"] <= 1.2 * V_CREEP and summary["rollback_guarded_m"] <= 0.005


@pytest.mark.parametrize(("grade", "pedal", "mass"), [(-0.27, 0.05, 1.0), (-0.30, 0.06, 1.0), (-0.33, 0.08, 1.0),
                                                      (-0.15, 0.05, 1.5), (-0.30, 0.04, 1.0)])
def test_a_light_pedal_downhill_does_not_end_the_tcus_hold(grade, pedal, mass):
    """Issue 37, finding 2: creeping downhill at 0.206 m/s, the driver's pedal at 5-8 % (counted as pressed, so the
    creep ends and with it the TCU's DecelRequest) cannot hold the vehicle on -0.27 to -0.33 rad: it ran away
    (8.51 m/s; here 0.78 m/s 3 s into the pedal on -0.30 rad). The TCU now overrules a pressed pedal that does not
    hold the vehicle (over its target by the drivability band and speeding up) with its brake request until the
    vehicle stands. Also at the range's steepest downhill with the heaviest vehicle and at 4 % (not pressed: the
    creep's DecelRequest holds the target)."""
    s = creep(6.0, [(1.0, True, 0.0, V_CREEP), (3.0, True, pedal, V_CREEP)], grade=grade, mass=mass)
    assert s["max_speed_creep_mps"] <= 1.5 * V_CREEP and s["overspeed_mps"] <= 0.5 * V_CREEP
    assert s["rollback_guarded_m"] <= 0.005


@pytest.mark.parametrize("mass", [1.0, 1.5])
def test_desired_speed_zero_with_creep_requested_holds_the_vehicle(mass):
    """Issue 37, finding 3: creep requested at 0 m/s is a stand, held by the TCU's brake request, and a creep asked
    to 0 afterwards launches as from rest. Before: the launch's pre-fill released the brake and the speed controller
    held 0 m/s on the clutch alone: on 0.25 rad Table I's vehicle rolled back 13.9 mm at 5.8 mm/s, 11.76 t at
    17.4 mm/s."""
    s = creep(7.0, [(1.0, True, 0.0, 0.0), (4.5, True, 0.0, V_CREEP)], grade=0.25, mass=mass)
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_m"] <= 0.005
    assert s["max_speed_creep_mps"] >= 0.5 * V_CREEP  # and it launched once asked to creep


R00037 = {"grade_rad": 0.2770859279886919, "engine_speed_rpm": 1307.129973522744,
          "initial.T_clutch_c": 116.3836170274385, "initial.T_oil_c": 80.18927544414302,
          "params.vehicle.m": 10695.682296966532, "driver.behaviour": "stop_and_go",
          "driver.desired_speed_mps": 0.3646941694001342, "driver.creep_s": 18.87823458187436,
          "driver.stop_s": 18.28015776594944, "driver.drag_level": 0.07817009417259108,
          "driver.drag_onset_s": 88.519835515886, "driver.drag_duration_s": 132.32703173904105,
          "latent": "gain:PLANT_PRESSURE.P_CH@0-,value=0.9176; offset:PLANT_VEHICLE.VehicleSpeed@0-,value=-0.01452"}


@pytest.mark.slow
def test_proof_found_a_light_pedal_with_vehicle_speed_reading_low_keeps_the_vehicle_held():
    """10.7 t on 0.277 rad, stop-and-go with the driver's foot resting at 7.8 % (pressed, too light for the slope),
    VehicleSpeed reading 14.5 mm/s low from key-on (within the speed vote until it has filled its distance; the
    safety proof sweep's batch 102, r00037, on the TCU with the key-on check): standing, the TCU read the vehicle as
    rolling back, so at the pedal's 7.8 % it left the vehicle to the pedal, which let it roll back 6.1 m at up to
    0.20 m/s (the limit: 0.05 m). The TCU now takes a braked vehicle whose speed reads steady, within what the vote
    lets through, as standing, keeps a vehicle that stood held until the next launch, and overrules a pedal it
    rolls back under."""
    s = sweep_run({**R00037, "duration_s": 125.0})
    assert s["rollback_m"] <= 0.05 and s["rollback_mps"] >= -ROLLBACK_MAX_MPS  # before: 1.0 m by 125 s


@pytest.mark.parametrize("offset", [-0.0145, 0.0145])
@pytest.mark.parametrize("pedal", [0.063, 1.0])
def test_a_vehicle_speed_reading_off_does_not_end_the_hold_or_roll_a_launch_back(offset, pedal):
    """VehicleSpeed off by 14.5 mm/s from key-on (beyond the 10-mm/s standstill band; the speed vote out-votes it
    once its distance to the shafts passes 40 mm, about 3 s), 11.76 t on 0.25 rad: standing under a light pedal
    (6.3 %: pressed, too light for the slope) or the full one for 1 s, then a launch. Before, the TCU never saw it
    stand: under 6.3 % its hold ended at once (249 mm/s back), the grade was never read and the launch's brake was
    released at once (110 mm/s back). Braked, its reading steady, it stands: it is held, and launches as without
    the fault."""
    scenario = worst_case(6.0, [(1.0, True, pedal, 0.0), (2.0, True, 0.0, V_CREEP)], grade=0.25)
    s = run_plant(scenario=scenario, params={"vehicle.m": load_params().vehicle.m * 1.5}, log=None,
                  faults=[f"offset:PLANT_VEHICLE.VehicleSpeed@0-,value={offset}"]).summary
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_m"] <= 0.05
    assert s["max_speed_creep_mps"] >= 0.5 * V_CREEP


@pytest.mark.parametrize(("grade", "mass", "pedal"), [(0.25, 1.5, 0.063), (0.25, 0.5, 0.063), (-0.15, 1.5, 1.0)])
def test_launches_at_the_ranges_ends_roll_back_at_most_10_mm_s(grade, mass, pedal):
    """Issue 37, item 4: a launch at an end of the operating range (the steepest grades, the heaviest and lightest
    vehicle), from a light pedal (6.3 %: pressed, but not holding 0.25 rad: the TCU's brake request holds) or the
    full brake, rolls back at most 10 mm/s and 50 mm."""
    text = (f'name = "launch"\nduration_s = 5.0\ngrade_rad = {grade}\nengine_speed_rpm = 800.0\n'
            "[initial]\nT_clutch_c = 100.0\nT_oil_c = 100.0\n"
            f"[[driver]]\nt_s = 0.0\nbrake = {pedal}\n"
            f"[[driver]]\nt_s = 1.5\ncreep_request = true\ndesired_speed_mps = {V_CREEP}\n")
    params = with_overrides(load_params(), {"vehicle.m": load_params().vehicle.m * mass})
    s = run_closed_loop(parse_scenario(text, "launch"), params).summary
    assert s["rollback_mps"] >= -ROLLBACK_MAX_MPS and s["rollback_m"] <= 0.05
    assert s["max_speed_creep_mps"] >= 0.5 * V_CREEP


R00374 = {"grade_rad": 0.08122283983515138, "engine_speed_rpm": 1978.2588912952815,
          "initial.T_clutch_c": 71.879546123436, "initial.T_oil_c": 96.07614737877678,
          "params.vehicle.m": 7334.714846476076, "driver.behaviour": "creep_toggles",
          "driver.desired_speed_mps": 0.22546866288533488, "driver.creep_s": 12.739187099341976,
          "driver.stop_s": 12.912121108958987, "driver.drag_level": 0.04715347508644651,
          "driver.drag_onset_s": 81.31601247311403, "driver.drag_duration_s": 156.9704664595582,
          "driver.speed_2_mps": 0.21402532227824927, "driver.change_s": 58.278625242687355,
          "driver.toggle_s": 3.8528318902267946, "driver.toggle_brake": False, "driver.stop_at_s": 153.90637455610806,
          "driver.pause_s": 59.45124603603561, "latent": "gain:PLANT_OIL_TEMP.T_OilCH@1.035-,value=0.9272"}


@pytest.mark.slow
def test_proof_found_an_oil_gain_beginning_while_the_oil_settles_keeps_the_true_plate_under_t_safe():
    """7.3 t on 0.081 rad, creep-request toggles, T_OilCH reading 7.3 % low (a gain: 0.9272 T in degC) from 1.035 s
    (the safety proof's batch 103, r00374, on the TCU of 5a14f67): the step came while the oil settled after key-on,
    before the fall check starts (1.6 s), and the oil balance check lets 7 K through; as CH heated the error grew
    to 17 K, and CH's true plate reached 254.1 degC under a prediction of 237.0. The settling check catches the
    step (a settling reading moves as its time constant says), and the margin budgets a gain's growth."""
    s = sweep_run(R00374)
    assert max(s["max_plate_temp_c"].values()) <= T_SAFE_C and s["min_margin_c"]["truth"] >= 0.0


R00176 = {"grade_rad": -0.09874905781427108, "engine_speed_rpm": 1912.485610247752,
          "initial.T_clutch_c": 151.98120020950398, "initial.T_oil_c": 102.65288802842487,
          "params.vehicle.m": 6628.234929185868, "driver.behaviour": "brake_drag",
          "driver.desired_speed_mps": 0.25755966463880653, "driver.drag_level": 0.022874036604051462,
          "driver.drag_onset_s": 151.124894426874, "driver.drag_duration_s": 225.21776138146353,
          "latent": "gain:PLANT_OIL_TEMP.T_OilCL@1.33-,value=0.9004; "
                    "gain:PLANT_SPEEDS.ClutchInputSpeed@111.393-,value=1.6686"}


@pytest.mark.slow
def test_proof_found_an_oil_gain_beginning_late_in_the_settling_keeps_the_true_plate_under_t_safe():
    """6.6 t on -0.099 rad with a brake drag, plates at 152 degC in 103-degC oil, T_OilCL reading 10 % low (a gain:
    0.9004 T in degC) from 1.33 s, and the clutch-input speed reading 1.67 times high from 111 s (the safety proof's
    batch 104, r00176, on the TCU of 5a14f67: CL's true plate reached 256.3 degC). The oil gain begins in the last
    quarter-second before the fall check starts (1.6 s); the settling check catches it and the margin budgets its
    growth."""
    s = sweep_run(R00176)
    assert max(s["max_plate_temp_c"].values()) <= T_SAFE_C and s["min_margin_c"]["truth"] >= 0.0


@pytest.mark.slow
@pytest.mark.parametrize("fault", [
    "gain:PLANT_OIL_TEMP.T_OilCL@1.035-,value=0.9272",  # before: 258.57 degC
    "gain:PLANT_OIL_TEMP.T_OilCL@0.5-,value=0.9",  # 10 %, before the creep begins; before: 268.22 degC
    "offset:PLANT_OIL_TEMP.T_OilCL@0.55-,value=-7",  # within the oil balance check's 10 K; before: 247.54, unflagged
])
def test_an_oil_step_while_the_oil_settles_after_key_on_is_caught(fault):
    """The default scenario (plates and oil at 100 degC), an oil reading stepping low between the key-on check (the
    first frame) and the fall check's start (1.6 s): before, nothing saw it (CL's true plate at the degC noted);
    the settling check flags it and the plate is predicted without cooling."""
    run = run_plant(log=None, faults=[fault])
    s = run.summary
    assert s["max_plate_temp_c"]["CL"] <= T_SAFE_C and s["min_margin_c"]["truth"] >= 0.0
    assert s["max_plate_temp_c"]["CL"] < 225.0  # flagged: CL handed over early, its plate predicted adiabatic
