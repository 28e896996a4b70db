"""The vehicle-speed plausibility vote (ecu_stub/plausibility.py) on hand cases: consistent speeds, VehicleSpeed
stuck at 0 or offset, standstill, the driveline's twist while a torque changes, no two speeds agreeing; and in the
runner: a stuck VehicleSpeed replaced by the shafts' speed (fault bit 4, counted), slip left alone."""

from __future__ import annotations

import math

import can
import pytest

from dsg_hil.protocol import Codec, TxScheduler, load_dbc
from dsg_hil.sim.plant_io import PLANT_USES
from ecu_stub.plausibility import (
    A_COAST_MPS2,
    A_GRIP_MPS2,
    DISTANCE_M,
    HEAL_S,
    TWIST_M,
    PeakHold,
    SpeedVoter,
    Verdict,
    plausible_step,
    shaft_speed_mps,
    tolerance_mps,
)
from ecu_stub.calibration import load_calibration
from ecu_stub.controller import TcuInputs, TcuOutputs
from ecu_stub.interface import TcuController
from ecu_stub.runner import FAULT_IMPLAUSIBLE, TCU_USES, TcuRunner

R_CL, R_CH = 0.034443, 0.059517  # the shipped calibration's speed ratios [m/s per rad/s]
DT = 0.01  # TCU_CMD cycle [s]


def rpm(v_mps: float, ratio: float) -> float:
    """The output speed [r/min] that turns at vehicle speed v."""
    return v_mps / ratio * 30.0 / math.pi


def voter() -> SpeedVoter:
    return SpeedVoter(R_CL, R_CH, 0.001, 0.1)  # the DBC's steps of VehicleSpeed and of the output speeds


def run(check: SpeedVoter, cycles, t0: float = 0.0, braked: bool = False) -> list[tuple[Verdict, float]]:
    """``cycles``: (VehicleSpeed, CL speed, CH speed) in m/s, one per 10-ms cycle from t0, a new frame each;
    ``braked``: a brake may add any deceleration (the TCU's own request)."""
    brake = math.inf if braked else 0.0
    return [check.update(v, rpm(v_cl, R_CL), rpm(v_ch, R_CH), t0 + k * DT, brake_mps2=brake)
            for k, (v, v_cl, v_ch) in enumerate(cycles)]


def test_shaft_speed_and_tolerance_by_hand():
    assert shaft_speed_mps(rpm(0.37, R_CL), R_CL) == pytest.approx(0.37, abs=1e-12)
    assert shaft_speed_mps(100.0, R_CL) == pytest.approx(0.034443 * 100.0 * math.pi / 30.0)  # 0.3607 m/s
    # half steps: 0.5 mm/s + 0.05 r/min x pi/30 x 0.034443 = 0.18 mm/s; 3 % of 0.37 m/s = 11.1 mm/s
    assert tolerance_mps(0.0, 0.37, 0.0005, 0.05 * math.pi / 30 * R_CL) == pytest.approx(0.0005 + 0.00018 + 0.0111,
                                                                                         abs=2e-6)


def test_the_twist_bound_is_the_driveline_compliance_of_table_i():
    """4 x (both clutches' largest wheel forces over shaft III's stiffness + CL's over its gear pair's), at the
    wheel: the number in the module docstring, recomputed from Table I and the calibration."""
    r_w, i_b, i_1, K_a2, K_a3 = 0.1935, 3.818, 0.925, 110088.0, 65114.0
    k_a3, k_a2 = K_a3 * (i_b / r_w) ** 2, K_a2 * (i_b * i_1 / r_w) ** 2
    F_cl, F_ch = 0.07 * 0.027337 * 1.5e6 / R_CL, 0.07 * 0.027337 * 1.5e6 / R_CH
    assert (k_a3, k_a2, F_cl, F_ch) == pytest.approx((2.535e7, 3.667e7, 83.34e3, 48.23e3), rel=1e-3)
    static = (F_cl + F_ch) / k_a3 + F_cl / k_a2
    assert static == pytest.approx(0.00746, abs=1e-5) and 4 * static <= TWIST_M
    assert DISTANCE_M == pytest.approx(0.040)


def test_consistent_speeds_pass_unchanged():
    check = voter()
    cycles = [(0.2 + 0.001 * k, 0.2 + 0.001 * k + 0.0004, 0.2 + 0.001 * k - 0.0003) for k in range(500)]
    assert run(check, cycles) == [(Verdict.OK, v) for v, _, _ in cycles]


def test_vehicle_speed_stuck_at_zero_is_replaced_by_the_shafts_speed_after_40_mm():
    """Creeping at 0.37 m/s, VehicleSpeed reads 0: beyond the tolerance by 0.37 - 0.01178 = 0.35822 m/s, i.e.
    3.5822 mm per cycle: past 40 mm after 12 cycles (42.99 mm; 39.40 mm after 11)."""
    check = voter()
    out = run(check, [(0.0, 0.37, 0.37)] * 20)
    assert all(verdict is Verdict.OK and v == 0.0 for verdict, v in out[:12])  # cycles 0 (no dt yet) .. 11
    assert out[12][0] is Verdict.SUBSTITUTED and out[12][1] == pytest.approx(0.37, abs=1e-12)
    assert all(verdict is Verdict.SUBSTITUTED for verdict, _ in out[12:])
    assert check.pairs[0].last_over == pytest.approx(0.12)  # then afresh: 7 more cycles
    assert check.pairs[0].over_m == [0.0, pytest.approx(0.0035822 * 7, abs=1e-6)]
    # the sensor comes back at 0.2 s: its step from 0 to 0.37 m/s in 10 ms is impossible (braked or not: no brake
    # speeds a vehicle up), so it is trusted again HEAL_S after that step, the shafts' speed used meanwhile (the
    # vote alone, HEAL_S after the bound was last passed at 0.12 s, would have trusted it at 2.12 s)
    back = run(check, [(0.37, 0.37, 0.37)] * 300, t0=0.2, braked=True)
    first_ok = next(k for k, (verdict, _) in enumerate(back) if verdict is Verdict.OK)
    assert first_ok == round(HEAL_S / DT) == 200
    assert all(r == (Verdict.SUBSTITUTED, pytest.approx(0.37)) for r in back[:first_ok])
    assert all(r == (Verdict.OK, 0.37) for r in back[first_ok:])


def test_an_intermittent_stuck_zero_adds_up():
    """Stuck for 9 cycles in 10 at 0.03 m/s (steps of 30 mm/s a coasting vehicle can make: no step check): each
    good cycle takes back only tol x 10 ms (0.016 mm), so the 9 x 0.28 mm of the stuck ones add up to 40 mm."""
    check = voter()
    cycles = [(0.03 if k % 10 == 9 else 0.0, 0.03, 0.03) for k in range(300)]
    out = run(check, cycles)
    first = next(k for k, (verdict, _) in enumerate(out) if verdict is not Verdict.OK)
    assert check.stepped_at is None
    assert 140 < first < 170 and all(verdict is Verdict.SUBSTITUTED for verdict, _ in out[first:])


def test_the_step_bounds_by_hand():
    """Coasting: g (sin 0.25 + 0.123 cos 0.25) = 3.60 m/s^2 (+10 %: 4); grip: 1.2 g + g sin 0.25 = 14.2 m/s^2; in
    one 10-ms frame, with two half steps of VehicleSpeed (1 mm/s): -41 mm/s .. +143 mm/s."""
    g = 9.81
    assert g * (math.sin(0.25) + 0.123 * math.cos(0.25)) == pytest.approx(3.596, abs=0.001)
    assert A_COAST_MPS2 == pytest.approx(1.1 * 3.596, abs=0.05)
    assert A_GRIP_MPS2 == pytest.approx(1.2 * g + g * math.sin(0.25), abs=0.02)
    q = 0.0005
    assert plausible_step(-0.0409, DT, q) and not plausible_step(-0.0411, DT, q)
    assert plausible_step(0.1429, DT, q) and not plausible_step(0.1431, DT, q)
    assert plausible_step(-0.12, 3 * DT, q)  # three frames: three times the change
    # a 1 % pedal may add 1 % of the calibration's full-pedal deceleration (52.7 m/s^2): -46.3 mm/s
    assert plausible_step(-0.0462, DT, q, 0.527) and not plausible_step(-0.0464, DT, q, 0.527)


def test_a_peak_hold_keeps_the_largest_of_its_window_and_what_follows_a_peak():
    """0.2-s window: 2.0 at 0, 1.5 at 0.1, 0 from 0.2: the largest is 2.0 until 0.2, then 1.5 (the value after the
    peak, still acting) until 0.3, then 0; a larger value hides the smaller ones before it at once."""
    hold = PeakHold(0.2)
    assert hold.peak(0.0) == 0.0
    for t, value in ((0.0, 2.0), (0.1, 1.5), (0.2, 0.0)):
        hold.add(t, value)
    assert hold.peak(0.2) == 2.0 and hold.peak(0.21) == 1.5
    hold.add(0.25, 0.0)
    assert hold.peak(0.3) == 1.5 and hold.peak(0.31) == 0.0
    hold.add(0.32, 0.5)
    hold.add(0.33, 1.0)
    assert hold.peak(0.33) == 1.0 and hold.peak(0.53) == 1.0 and hold.peak(0.54) == 0.0
    hold.clear()
    assert hold.peak(0.54) == 0.0
    falling = PeakHold(0.2)  # a long, slowly falling series added, never asked: it holds one window, not the series
    for k in range(10_000):
        falling.add(0.01 * k, 100.0 - 0.001 * k)
    assert len(falling._seen) <= 21  # one window of 10-ms values
    assert falling.peak(99.99) == pytest.approx(100.0 - 0.001 * 9_979)  # 0.2 s back: from k = 9,979 on


def test_vehicle_speed_stuck_at_zero_while_creeping_unbraked_is_replaced_at_the_step():
    """0.187 m/s, then 0 (r00450 of the 1,000-run sample): the shafts' speed from the first cycle at 0, then the
    vote takes over (40 mm after 0.23 s) and keeps it; before, the controller saw 0 for those 0.23 s."""
    check = voter()
    out = run(check, [(0.187, 0.187, 0.187)] * 10 + [(0.0, 0.187, 0.187)] * 60)
    assert all(r == (Verdict.OK, 0.187) for r in out[:10])
    assert all(r == (Verdict.SUBSTITUTED, pytest.approx(0.187)) for r in out[10:])
    assert check.pairs[0].last_over is not None  # the vote confirmed it
    # braking: the plant's brake may stop the vehicle within a cycle, so the vote alone judges: 1.81 mm per cycle
    # beyond the tolerance (6.3 mm/s), past 40 mm in the 23rd cycle at 0
    check = voter()
    out = run(check, [(0.187, 0.187, 0.187)] * 10 + [(0.0, 0.187, 0.187)] * 60, braked=True)
    first = next(k for k, (verdict, _) in enumerate(out) if verdict is not Verdict.OK)
    assert first == 10 + 22 and all(r == (Verdict.OK, 0.0) for r in out[10:first])


def test_a_step_within_what_a_vehicle_can_do_is_left_to_the_vote():
    """0.035 m/s -> 0 in one frame is a plausible coasting stop (3.5 m/s^2): no substitution before the vote."""
    check = voter()
    out = run(check, [(0.035, 0.035, 0.035)] * 10 + [(0.0, 0.035, 0.035)] * 20)
    assert all(verdict is Verdict.OK for verdict, _ in out)


def test_a_one_cycle_spike_is_substituted_until_the_distances_are_back_to_zero():
    """One frame at 0 while creeping at 0.2 m/s: the shafts' speed for that cycle and while VehicleSpeed's
    distance to the shafts (2 mm, taken back at the tolerance, 7.7 mm/s) lasts: 0.25 s; then VehicleSpeed again."""
    check = voter()
    out = run(check, [(0.2, 0.2, 0.2)] * 10 + [(0.0, 0.2, 0.2)] + [(0.2, 0.2, 0.2)] * 100)
    back = next(k for k, (verdict, _) in enumerate(out) if k > 10 and verdict is Verdict.OK)
    assert all(r == (Verdict.SUBSTITUTED, pytest.approx(0.2)) for r in out[10:back])
    assert 10 + 20 <= back <= 10 + 30 and all(r == (Verdict.OK, 0.2) for r in out[back:])


def test_the_step_is_timed_by_the_frame_counter():
    """A frame not renewed (the same counter) is no step; a counter that moved by 4 allows four frames' change;
    after a gap the control cycles' time counts if longer; a step beyond the bounds in one frame is caught."""
    check = voter()
    steps = [(0.3, 1, 0.0), (0.3, 1, 0.01), (0.2, 5, 0.02), (0.0, 6, 3.0)]  # -0.1 m/s over 4 frames: 2.5 m/s^2
    out = [check.update(v, rpm(v, R_CL), rpm(v, R_CH), t, counter=n) for v, n, t in steps]
    assert all(verdict is Verdict.OK for verdict, _ in out) and check.stepped_at is None
    # +0.3 m/s in one frame while the shafts stay at rest: impossible, the shafts' speed used
    assert check.update(0.3, 0.0, 0.0, 3.01, counter=7) == (Verdict.SUBSTITUTED, 0.0)
    assert check.stepped_at == 3.01


def test_a_gap_in_the_frames_counts_one_timeout_at_most():
    """After 2 s without valid frames (FAULT), the first cycle counts 30 ms (MAX_DT_S), not 2 s."""
    check = voter()
    assert check.update(0.2, rpm(0.2, R_CL), rpm(0.2, R_CH), 0.0) == (Verdict.OK, 0.2)
    assert check.update(0.0, rpm(0.5, R_CL), rpm(0.5, R_CH), 2.0) == (Verdict.OK, 0.0)  # 0.5 m/s x 30 ms = 15 mm
    assert check.pairs[0].over_m[1] == pytest.approx((0.5 - 0.0005 - 0.05 * math.pi / 30 * R_CL - 0.015) * 0.03)


def test_an_offset_vehicle_speed_is_caught_when_its_distance_passes_the_bound_and_not_within_the_tolerance():
    # +0.1 m/s at 0.2 m/s: beyond tol (0.68 mm/s + 3 % of 0.3 m/s = 9.68 mm/s) by 90.32 mm/s: 44.3 cycles
    check = voter()
    out = run(check, [(0.3, 0.2, 0.2)] * 60)
    first = next(k for k, (verdict, _) in enumerate(out) if verdict is not Verdict.OK)
    assert first == 45 and out[first] == (Verdict.SUBSTITUTED, pytest.approx(0.2))
    # +5 mm/s at 0.2 m/s is within the tolerance (6.7 mm/s + 0.68 mm/s): never, however long
    check = voter()
    assert all(verdict is Verdict.OK for verdict, _ in run(check, [(0.205, 0.2, 0.2)] * 3000))


def test_at_standstill_a_stuck_zero_is_plausible_and_harmless():
    check = voter()
    assert all(r == (Verdict.OK, 0.0) for r in run(check, [(0.0, 0.0, 0.0)] * 200))
    assert all(r == (Verdict.OK, 0.0005) for r in run(check, [(0.0005, -0.0001, 0.0002)] * 200, t0=2.0))


def test_one_output_speed_off_leaves_vehicle_speed_in_use():
    """VehicleSpeed agrees with CH: used as it is (CL's output speed alone is off: 2 of 3 still agree)."""
    check = voter()
    assert all(r == (Verdict.OK, 0.3) for r in run(check, [(0.3, 0.0, 0.3)] * 300))


def test_twist_while_a_torque_changes_is_no_fault():
    """During slip the clutch input turns faster than the outputs, which the vote does not look at; but the
    outputs' speeds also differ from the wheel's while the shafts wind up: a 88-Hz ringing of +-0.15 m/s sampled
    every 10 ms, and a wind-up that puts 30 mm (TWIST_M) between them at 0.3 m/s over 0.1 s, pass; 60 mm does not."""
    check = voter()
    ringing = [(0.2, 0.2 + 0.15 * math.sin(2 * math.pi * 88.0 * k * DT), 0.2) for k in range(1000)]
    assert all(verdict is Verdict.OK for verdict, _ in run(check, ringing))
    check = voter()
    wind_up = [(0.2, 0.2 + 0.3 + 0.0157, 0.2 + 0.3 + 0.0157)] * 11 + [(0.2, 0.2, 0.2)] * 50  # 10 dt x 0.3 m/s
    assert all(verdict is Verdict.OK for verdict, _ in run(check, wind_up))
    check = voter()
    twice = [(0.2, 0.2 + 0.6 + 0.025, 0.2 + 0.6 + 0.025)] * 11  # 10 dt x 0.6 m/s: 60 mm
    assert run(check, twice)[-1][0] is Verdict.SUBSTITUTED


def test_a_disagreement_that_changes_sides_starts_again():
    """0.3 m/s apart, the side swapped every 8 cycles (24 mm each way): never 40 mm on one side."""
    check = voter()
    cycles = [(0.2, 0.2 + (0.3 if (k // 8) % 2 else -0.3), 0.2 + (0.3 if (k // 8) % 2 else -0.3)) for k in range(400)]
    assert all(verdict is Verdict.OK for verdict, _ in run(check, cycles))


def test_no_two_speeds_agreeing_is_a_fault():
    check = voter()
    out = run(check, [(0.0, 0.3, 0.6)] * 40)
    assert out[-1] == (Verdict.FAULT, 0.0) and out[0] == (Verdict.OK, 0.0)
    check.reset()
    assert check.update(0.0, 0.0, 0.0, 10.0) == (Verdict.OK, 0.0)


# ---- in the runner ------------------------------------------------------------------------------------------

@pytest.fixture()
def bus():
    null = _NullBus()
    yield null
    null.shutdown()


def tcu_with(speeds: dict, vehicle: dict, now: float, tcu: TcuRunner | can.BusABC,
             plant: TxScheduler | None = None, driver: dict | None = None,
             controller: TcuController | None = None) -> tuple[TcuRunner, TxScheduler]:
    """Given a bus: a TCU on it (real time; ``controller``, default ecu-stub's), given one set of plant frames at
    ``now``; given that TCU and its plant schedule, the next set of frames."""
    if not isinstance(tcu, TcuRunner):
        tcu = TcuRunner(Codec(load_dbc(), TCU_USES), tcu, controller)
        plant = TxScheduler(Codec(load_dbc(), PLANT_USES), ["PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE",
                                                            "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER"])
    assert plant is not None
    values = {"PLANT_SPEEDS": speeds, "PLANT_VEHICLE": vehicle, "DRIVER": driver or {}}
    for name in ("PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER"):
        tcu.handle(plant.frame(name, values.get(name, {})), now)
    return tcu, plant


class _NullBus(can.BusABC):
    """Nothing to receive; what is sent is dropped."""

    def __init__(self) -> None:
        super().__init__(channel="null")

    def send(self, msg, timeout=None):
        pass

    def _recv_internal(self, timeout):
        return None, False


def test_runner_keeps_vehicle_speed_through_slip_and_replaces_a_stuck_one(bus):
    v = 0.2
    slipping = {"ClutchInputSpeed": 149.3, "CLOutputSpeed": round(rpm(v, R_CL), 1), "CHOutputSpeed":
                round(rpm(v, R_CH), 1)}  # CL slips 93.8 r/min, CH 117.2 r/min
    tcu, plant = tcu_with(slipping, {"TransOutputSpeed": 41.2, "VehicleSpeed": v}, 0.0, bus)
    for k in range(1, 100):
        inp = tcu.inputs(k * DT)
        tcu_with(slipping, {"TransOutputSpeed": 41.2, "VehicleSpeed": v}, k * DT, tcu, plant)
        assert inp.plant_valid and inp.v_mps == v and inp.fault_bits == 0
    assert set(tcu.frame_counts()["implausible"].values()) == {0}  # (the thermal inputs' checks too)
    assert {"VehicleSpeed", "speeds"} <= set(tcu.frame_counts()["implausible"])
    got = []
    for k in range(100, 140):  # VehicleSpeed stuck at 0 (CRC and counter valid)
        tcu_with(slipping, {"TransOutputSpeed": 41.2, "VehicleSpeed": 0.0}, k * DT, tcu, plant)
        got.append(tcu.inputs(k * DT))
    # at once: 0.2 m/s to 0 in one frame is more than an unbraked vehicle decelerates (the vote would take 22 cycles)
    assert all(inp.plant_valid and inp.v_mps == pytest.approx(v, abs=0.001) for inp in got)
    assert all(inp.fault_bits == FAULT_IMPLAUSIBLE for inp in got)
    assert tcu.frame_counts()["implausible"]["VehicleSpeed"] == 40


@pytest.mark.parametrize("pedal, at_once", [(2.0, True), (50.0, False)])
def test_runner_allows_for_the_drivers_brake_in_the_step(bus, pedal, at_once):
    """The driver's foot on the pedal: the brake may add pedal x 52.7 m/s^2 (the calibration's full-pedal
    deceleration of the lightest vehicle). At 2 %: 0.2 m/s to 0 in one frame (20 m/s^2) is still more than
    4 + 1.05 m/s^2, caught at once; at 50 % (30 m/s^2) it is a brake stop, left to the vote (22 cycles)."""
    v, drag = 0.2, {"BrakePedal": pedal}
    slipping = {"ClutchInputSpeed": 149.3, "CLOutputSpeed": round(rpm(v, R_CL), 1), "CHOutputSpeed":
                round(rpm(v, R_CH), 1)}
    tcu, plant = tcu_with(slipping, {"VehicleSpeed": v}, 0.0, bus, driver=drag)
    for k in range(1, 10):
        assert tcu.inputs(k * DT).v_mps == v
        tcu_with(slipping, {"VehicleSpeed": v}, k * DT, tcu, plant, driver=drag)
    got = []
    for k in range(10, 40):
        tcu_with(slipping, {"VehicleSpeed": 0.0}, k * DT, tcu, plant, driver=drag)
        got.append(tcu.inputs(k * DT))
    assert got[0].brake_pct == pedal
    if at_once:
        assert all(inp.v_mps == pytest.approx(v, abs=0.001) and inp.fault_bits == FAULT_IMPLAUSIBLE for inp in got)
    else:
        assert got[0].v_mps == 0.0 and got[0].fault_bits == 0
        assert got[-1].v_mps == pytest.approx(v, abs=0.001) and got[-1].fault_bits == FAULT_IMPLAUSIBLE


class _Braking:
    """A :class:`~ecu_stub.interface.TcuController` (not a subclass: the compiled build's CreepController cannot be
    subclassed by Python code) with the shipped calibration, so the runner votes the speeds with it: asks the brakes
    for a fixed deceleration (DecelRequest) or the full brake (BrakeRequest) every cycle; keeps the inputs it is
    given."""

    def __init__(self, decel_mps2: float, full: bool) -> None:
        self.cal = load_calibration()
        self.decel_mps2, self.full = decel_mps2, full
        self.seen: list[TcuInputs] = []

    def update(self, inputs: TcuInputs, now: float) -> TcuOutputs:
        self.seen.append(inputs)
        return TcuOutputs(0.0, 0.0, "CREEP", "CL", self.full, 60.0, 60.0, 0, self.decel_mps2)


@pytest.mark.parametrize("decel, full, v_after, at_once", [(0.0, False, 0.15, True), (1.0, False, 0.15, False),
                                                          (1.0, False, 0.0, True), (0.0, True, 0.0, False)])
def test_runner_allows_for_its_own_deceleration_request_in_the_step(bus, decel, full, v_after, at_once):
    """The TCU's own requests: a deceleration asked (DecelRequest) lets the brakes add that much and half its
    0.05 m/s^2 step. 0.2 -> 0.15 m/s in one frame (-50 mm/s) is beyond an unbraked vehicle's -41 mm/s (caught at
    once), within -(4 + 1.025) x 0.01 - 0.001 = -51.25 mm/s with 1 m/s^2 asked (left to the vote); 0.2 -> 0 is
    caught with 1 m/s^2 asked too; the full brake asked (BrakeRequest) allows any."""
    v = 0.2
    slipping = {"ClutchInputSpeed": 149.3, "CLOutputSpeed": round(rpm(v, R_CL), 1), "CHOutputSpeed":
                round(rpm(v, R_CH), 1)}
    controller = _Braking(decel, full)
    tcu, plant = tcu_with(slipping, {"VehicleSpeed": v}, 0.0, bus, controller=controller)
    for k in range(1, 10):
        tcu.control((k - 1) * DT)
        tcu_with(slipping, {"VehicleSpeed": v}, k * DT, tcu, plant)
    for k in range(10, 40):
        tcu.control((k - 1) * DT)
        tcu_with(slipping, {"VehicleSpeed": v_after}, k * DT, tcu, plant)
    tcu.control(39 * DT)
    got = controller.seen[10:]
    assert all(inp.v_mps == v for inp in controller.seen[1:10])
    if at_once:
        assert all(inp.v_mps == pytest.approx(v, abs=0.001) and inp.fault_bits == FAULT_IMPLAUSIBLE for inp in got)
    else:
        assert got[0].v_mps == v_after and got[0].fault_bits == 0


def test_runner_goes_to_fault_when_no_speed_can_be_trusted(bus):
    tcu, plant = tcu_with({"CLOutputSpeed": 0.0, "CHOutputSpeed": 100.0}, {"VehicleSpeed": 0.3}, 0.0, bus)
    inp = None
    for k in range(1, 60):
        tcu_with({"CLOutputSpeed": 0.0, "CHOutputSpeed": 100.0}, {"VehicleSpeed": 0.3}, k * DT, tcu, plant)
        inp = tcu.inputs(k * DT)
    assert inp is not None and not inp.plant_valid and inp.fault_bits == FAULT_IMPLAUSIBLE
    assert tcu.frame_counts()["implausible"]["speeds"] > 0


def test_the_speed_vote_counts_frames_with_the_profiles_counter_range(bus):
    """PLANT_VEHICLE under AUTOSAR Profile 1 (counter 0..14; its Counter and CRC signals the profile's fields): the
    vote counts the frames between two VehicleSpeed values modulo 15, not 16."""
    p01 = {"profile": "P01", "data_id": 0x102, "crc_offset": 56, "counter_offset": 48}
    tcu = TcuRunner(Codec(load_dbc(), TCU_USES, protection={"PLANT_VEHICLE": p01}), bus)
    default = TcuRunner(Codec(load_dbc(), TCU_USES), bus)
    assert tcu.speed_vote is not None and default.speed_vote is not None
    assert (tcu.speed_vote.counter_modulus, default.speed_vote.counter_modulus) == (15, 16)


def test_an_output_speed_off_both_others_is_out_voted_for_the_slip():
    """CL's output speed alone off (VehicleSpeed and CH agree): VehicleSpeed stays in use and CL's output speed is
    named out-voted (the runner then takes v / r_CL for CL's slip); VehicleSpeed off (the shafts agree): none."""
    check = voter()
    out = run(check, [(0.3, 0.0, 0.3)] * 300)
    assert all(r == (Verdict.OK, 0.3) for r in out) and check.outvoted == "CL"
    check = voter()
    run(check, [(0.2, 0.2, 0.3)] * 300)
    assert check.outvoted == "CH"
    check = voter()
    out = run(check, [(0.0, 0.3, 0.3)] * 300)
    assert out[-1][0] is Verdict.SUBSTITUTED and check.outvoted == ""
    check = voter()
    run(check, [(0.3, 0.3 * 1.02, 0.3)] * 300)  # within the 3 % tolerance: never
    assert check.outvoted == ""
