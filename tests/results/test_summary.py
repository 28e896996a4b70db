"""The summary's definitions (dsg_hil.results.summary) on hand-built plant output sequences."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from dsg_hil.physics.plant import PlantOutputs
from dsg_hil.results.summary import CreepMetrics, RunSummary

DT = 0.01
W_IN = 100.0  # rad/s, clutch input
BASE = {f: 0.0 for f in PlantOutputs._fields} | {"omega_in": W_IN, "omega_CL": W_IN, "omega_CH": W_IN,
                                                  "T_CL": 100.0, "T_CH": 100.0, "locked_CL": False,
                                                  "locked_CH": False, "vehicle_held": False}


def out(t: float, **kw) -> PlantOutputs:
    return PlantOutputs(**(BASE | {"t": t} | kw))


def feed(m: CreepMetrics, seconds: float, t0: float, creep: bool = True, desired: float = 0.1, **kw) -> float:
    """``seconds`` of identical samples from ``t0``; returns the time after them."""
    n = round(seconds / DT)
    for k in range(n):
        m.add(out(t0 + k * DT, **kw), DT, creep, desired)
    return t0 + n * DT


CL_SLIPS = {"omega_CL": 20.0, "M_CL": 300.0, "P_CL": 0.5e6}
CH_SLIPS = {"omega_CH": 30.0, "M_CH": 300.0, "P_CH": 0.7e6}


def test_crossover_is_counted_once_for_the_clutch_with_the_larger_torque():
    m = CreepMetrics()
    t = feed(m, 1.0, 0.0, v=0.1, **CL_SLIPS)
    t = feed(m, 0.1, t, v=0.1, **CL_SLIPS | CH_SLIPS | {"M_CH": 100.0})  # both slip, CL drives
    t = feed(m, 0.1, t, v=0.1, **CL_SLIPS | CH_SLIPS | {"M_CL": 100.0})  # both slip, CH drives
    feed(m, 1.0, t, v=0.1, **CH_SLIPS)
    j = m.as_json()
    assert j["slip_time_s"]["CL"] == pytest.approx(1.1) and j["slip_time_s"]["CH"] == pytest.approx(1.1)
    assert j["slip_overlap_s"] == pytest.approx(0.2)
    assert sum(j["slip_time_s"].values()) == pytest.approx(2.2)  # the time during which some clutch slips
    assert [(p["clutch"], p["start_s"], p["end_s"]) for p in j["phases"]] == [("CL", 0.0, 1.1), ("CH", 1.1, 2.2)]


def test_a_locked_or_open_clutch_does_not_slip():
    m = CreepMetrics()
    feed(m, 1.0, 0.0, v=0.1, M_CL=300.0)  # torque, no slip: locked
    feed(m, 1.0, 1.0, v=0.1, omega_CL=20.0, M_CL=2.0)  # slip, no torque: open
    assert m.as_json()["slip_time_s"] == {"CL": 0.0, "CH": 0.0}


def test_without_truth_torque_the_pressure_tells_which_clutch_transmits():
    m = CreepMetrics()
    feed(m, 1.0, 0.0, v=0.1, omega_CL=20.0, M_CL=float("nan"), P_CL=0.5e6)
    feed(m, 1.0, 1.0, v=0.1, omega_CL=20.0, M_CL=float("nan"), P_CL=0.01e6)
    assert m.as_json()["slip_time_s"]["CL"] == pytest.approx(1.0)


def test_roll_back_and_standstill_while_creep_is_requested():
    m = CreepMetrics()
    t = feed(m, 1.0, 0.0, creep=False, v=0.0)  # braked, no request: neither creep nor standstill
    t = feed(m, 0.5, t, v=-0.04, **CL_SLIPS)  # rolls back
    t = feed(m, 1.5, t, v=0.0, **CL_SLIPS)  # stands
    feed(m, 2.0, t, v=0.1, **CL_SLIPS)  # creeps
    j = m.as_json()
    assert j["rollback_mps"] == pytest.approx(-0.04) and j["rollback_m"] == pytest.approx(0.02)
    assert j["standstill_time_s"] == pytest.approx(1.5)
    assert j["creep_time_s"] == pytest.approx(2.0)
    assert j["stop_time_s"] is None and j["stop_reason"] == "end_of_record"


def test_creep_time_needs_no_tcu_status():
    """A third-party ECU that sends no TCU_STATUS: creep time from the driver's request and the vehicle."""
    m = CreepMetrics()
    feed(m, 3.0, 0.0, v=0.1, **CL_SLIPS)
    j = m.as_json()
    assert j["creep_time_s"] == pytest.approx(3.0)
    assert j["max_predicted_temp_c"] == {"CL": None, "CH": None}
    assert j["worst_prediction_error_c"] == {"CL": None, "CH": None} and j["handovers"] == []


def test_stop_is_the_start_of_the_final_rest_while_creep_is_requested():
    m = CreepMetrics()
    t = feed(m, 2.0, 0.0, v=0.1, **CL_SLIPS, T_CL=230.0)
    t = feed(m, 1.0, t, v=0.0, **CL_SLIPS, T_CL=240.0)  # a short rest (a handover dip) ...
    t = feed(m, 2.0, t, v=0.1, **CL_SLIPS, T_CL=245.0)  # ... is not the stop
    feed(m, 3.0, t, v=0.0, T_CL=246.0)  # rests until the end of the record
    j = m.as_json()
    assert j["stop_time_s"] == pytest.approx(5.0) and j["T_CL_at_stop_c"] == 246.0
    assert j["stop_reason"] == "vehicle_stopped"
    assert j["standstill_time_s"] == pytest.approx(4.0) and j["creep_time_s"] == pytest.approx(4.0)
    assert j["speed_min_creeping_mps"] == 0.0


def test_a_rest_shorter_than_the_stop_time_at_the_end_is_no_stop():
    m = CreepMetrics()
    t = feed(m, 2.0, 0.0, v=0.1, **CL_SLIPS)
    feed(m, 1.0, t, v=0.0)
    assert m.as_json()["stop_time_s"] is None


def test_time_above_the_limit_and_friction_energy():
    m = CreepMetrics()
    t = feed(m, 2.0, 0.0, v=0.1, **CL_SLIPS, T_CL=249.0, Q_CL=1000.0)
    feed(m, 1.5, t, v=0.1, **CH_SLIPS, T_CL=251.0, T_CH=250.0, Q_CH=3000.0)  # exactly 250 is not above
    j = m.as_json()
    assert j["time_above_limit_s"] == {"CL": pytest.approx(1.5), "CH": 0.0}
    assert j["friction_energy_kj"] == {"CL": pytest.approx(2.0), "CH": pytest.approx(4.5)}
    assert j["max_plate_temp_c"] == {"CL": 251.0, "CH": 250.0}


def test_first_ch_phase_values_outside_the_crossovers():
    m = CreepMetrics()
    t = feed(m, 2.0, 0.0, v=0.1, **CL_SLIPS)
    t = feed(m, 0.2, t, v=0.1, **CL_SLIPS | CH_SLIPS | {"M_CL": 100.0, "P_CH": 1.2e6})  # crossover ramps
    for k in range(300):  # CH alone 3 s: mu rises, P falls, T_CL cools
        m.add(out(t + k * DT, v=0.1, **CH_SLIPS | {"mu_CH": 0.06 + 1e-4 * k, "P_CH": 0.8e6 - 1e3 * k,
                                                   "T_CL": 240.0 - 0.1 * k}), DT, True, 0.1)
    t += 3.0
    feed(m, 1.0, t, v=0.1, **CL_SLIPS | {"T_CL": 150.0})
    j = m.as_json()
    assert [p["clutch"] for p in j["phases"]] == ["CL", "CH", "CL"]
    assert j["mu_CH_first_slip"] == {"start": pytest.approx(0.065), "end": pytest.approx(0.0849)}  # 0.5 s in/out
    assert j["P_CH_first_slip_mpa"] == {"start": pytest.approx(0.75), "end": pytest.approx(0.551)}
    assert j["T_CL_at_first_CH_limit_c"] == pytest.approx(240.0 - 29.9)  # at CH's last instant alone


def test_prediction_error_is_the_worst_by_magnitude_with_its_time():
    m = CreepMetrics()
    m.status(0.1, 2, 1, 195.0, 100.0, out(0.1, T_CL=200.0))
    m.status(0.2, 2, 1, 203.0, 100.5, out(0.2, T_CL=200.0))
    m.status(0.3, 2, 2, 210.0, 101.0, out(0.3, T_CL=200.0, T_CH=100.0))
    j = m.as_json()
    assert j["worst_prediction_error_c"]["CL"] == {"error_c": 10.0, "t_s": 0.3}
    assert j["worst_prediction_error_c"]["CH"] == {"error_c": 1.0, "t_s": 0.3}
    assert j["max_predicted_temp_c"] == {"CL": 210.0, "CH": 101.0}
    assert [(h["from"], h["to"]) for h in j["handovers"]] == [("CL", "CH")]


def test_a_stop_or_clutch_the_next_frame_does_not_confirm_is_not_taken():
    """The CI flood (test_robustness): one random frame with TCU_STATUS's ID passed CRC and counter and said
    STOPPED_OVERHEAT between ENGAGE and CREEP frames; the record took it as the TCU's stop. A stop or a change of the
    active clutch is taken when the next frame confirms it, dated at its first frame; the rest counts at once."""
    m = CreepMetrics()
    m.status(1.1, 1, 1, 100.1, 100.0, out(1.1))  # ENGAGE on CL
    m.status(1.2, 4, 0, 154.2, -20.7, out(1.2))  # the CI flood's frame: STOPPED_OVERHEAT, no clutch
    assert m.tcu_state == "STOPPED_OVERHEAT"  # at once: roll-back from here counts as the TCU's (the safe side)
    m.status(1.5, 2, 1, 101.0, 100.0, out(1.5))  # CREEP on CL
    m.status(1.6, 2, 2, 102.0, 100.0, out(1.6))  # a single frame on CH: no handover
    m.status(1.7, 2, 1, 103.0, 100.0, out(1.7))
    m.status(1.8, 2, 2, 104.0, 101.0, out(1.8, T_CL=200.0))  # a handover, confirmed by the next frame
    m.status(1.9, 4, 2, 105.0, 101.0, out(1.9))  # a stop, confirmed by the next frame
    m.status(2.0, 4, 2, 105.0, 101.0, out(2.0))
    j = m.as_json()
    assert j["status_unconfirmed"] == 2
    assert (j["tcu_stop_time_s"], j["stop_reason"]) == (1.9, "STOPPED_OVERHEAT")
    assert [(h["t_s"], h["from"], h["to"], h["T_CL_c"]) for h in j["handovers"]] == [(1.8, "CL", "CH", 200.0)]
    assert j["max_predicted_temp_c"] == {"CL": 154.2, "CH": 101.0}  # predictions as heard, each frame


def test_the_last_frame_has_nothing_to_refute_it():
    m = CreepMetrics()
    m.status(0.1, 2, 1, 100.0, 100.0, out(0.1))
    m.status(0.2, 4, 2, 100.0, 100.0, out(0.2))
    j = m.as_json()
    assert (j["tcu_stop_time_s"], j["stop_reason"], j["status_unconfirmed"]) == (0.2, "STOPPED_OVERHEAT", 0)
    assert [(h["from"], h["to"]) for h in j["handovers"]] == [("CL", "CH")]


def test_the_speed_through_a_handover_begun_in_the_band_is_judged_until_1_s_after_it():
    """Through each handover (TCU_STATUS HANDOVER, and 1 s after its last frame) that began with the speed within
    20 % of the desired: the worst |v - desired| / desired. Not before, not 1 s after, not one begun launching."""
    m = CreepMetrics()
    t = feed(m, 0.5, 0.0, desired=0.2, v=0.5)  # before any handover: not judged (+150 %)
    m.status(t, 2, 1, 100.0, 100.0, out(t))
    m.status(t, 3, 2, 100.0, 100.0, out(t))  # HANDOVER to CH, begun at 0.21 m/s (in the band)
    t = feed(m, 0.3, t, desired=0.2, v=0.21)
    t = feed(m, 0.2, t, desired=0.2, v=0.17)  # a dip: -15 %
    m.status(t, 2, 2, 100.0, 100.0, out(t))  # CREEP on CH from 1.0 s: the window runs to 2.0 s
    t = feed(m, 0.9, t, desired=0.2, v=0.25)  # an overshoot after the crossover: +25 %
    m.status(t, 2, 2, 100.0, 100.0, out(t))  # 1.9 s
    t = feed(m, 0.2, t, desired=0.2, v=0.26)  # within the window until the status of 2.1 s: +30 %
    m.status(t, 2, 2, 100.0, 100.0, out(t))  # 2.1 s: past 2.0 s, the window is closed
    feed(m, 0.5, t, desired=0.2, v=0.4)  # not judged
    assert m.as_json()["handover_deviation_pct"] == pytest.approx(30.0)
    launching = CreepMetrics()
    launching.status(0.0, 3, 2, 100.0, 100.0, out(0.0))  # a handover begun at 0.1 m/s of 0.2: not judged
    feed(launching, 1.0, 0.0, desired=0.2, v=0.1)
    assert launching.as_json()["handover_deviation_pct"] is None
    assert CreepMetrics().as_json()["handover_deviation_pct"] is None
    stopped = CreepMetrics()
    stopped.status(0.0, 3, 2, 100.0, 100.0, out(0.0))
    feed(stopped, 0.5, 0.0, desired=0.2, v=0.2)
    feed(stopped, 0.1, 0.5, desired=0.2, v=0.0)  # the driver's brake: its stop is not the handover's
    stopped.status(0.6, 0, 0, 100.0, 100.0, out(0.6))  # IDLE: the window ends, not judged
    feed(stopped, 0.5, 0.6, desired=0.2, v=0.0)
    assert stopped.as_json()["handover_deviation_pct"] is None
    changed = CreepMetrics()
    changed.status(0.0, 3, 2, 100.0, 100.0, out(0.0))
    feed(changed, 0.5, 0.0, desired=0.2, v=0.2)
    feed(changed, 0.5, 0.5, desired=0.05, v=0.2)  # the driver asks for 0.05 m/s: the speed follows a new ramp
    changed.status(1.0, 2, 2, 100.0, 100.0, out(1.0))
    feed(changed, 1.2, 1.0, desired=0.05, v=0.1)
    changed.status(2.2, 2, 2, 100.0, 100.0, out(2.2))
    assert changed.as_json()["handover_deviation_pct"] is None


def periods(s: RunSummary, seconds: float, t0: float, v: float, desired: float = 0.2) -> float:
    """``seconds`` of identical 10-step periods through RunSummary.on_period (creep requested); the time after."""
    sample = lambda r: PlantOutputs(*r.tolist())  # noqa: E731
    n = round(seconds / DT / 10)
    for k in range(n):
        rows = np.array([[float(x) for x in out(round(t0 + (10 * k + j) * DT, 9), v=v)] for j in range(10)])
        s.on_period(rows, PlantOutputs._fields, sample, True, False, desired)
    return t0 + n * 10 * DT


def handover_with_a_dip(s: RunSummary, brake_at: float | None) -> dict:
    """A handover begun on the desired 0.2 m/s, a dip to 0.15 m/s (-25 %) from 0.5 s into it, back on 0.2 m/s; the
    driver's pedal goes above 0 at ``brake_at`` [s] (None: never) and stays."""
    status = {"State": 2.0, "ActiveClutch": 1.0, "T_CL_Pred": 100.0, "T_CH_Pred": 100.0}  # CREEP on CL
    t = 0.0
    for t_end, v, state in ((0.5, 0.2, None), (1.0, 0.2, 3.0), (1.5, 0.15, 2.0), (2.6, 0.2, 2.0), (3.0, 0.2, 2.0)):
        if brake_at is not None and t <= brake_at < t_end:
            t = periods(s, brake_at - t, t, v)
            s.on_driver_brake(True)
        t = periods(s, t_end - t, t, v)
        if state is None:
            s.on_status(t, status, out(t))
            status |= {"State": 3.0, "ActiveClutch": 2.0}
            s.on_status(t, status, out(t))  # HANDOVER to CH at 0.5 s
        else:  # (0.1-s frames, only those that matter: CREEP from 1.5 s, the window to 2.5 s; closed at 2.6 s)
            s.on_status(t, status | {"State": state}, out(t))
    return s.creep.as_json()


@pytest.mark.parametrize("brake_at, unbraked", [(None, 25.0), (0.8, None), (2.0, None), (2.8, 25.0),
                                                (0.2, None)])
def test_a_handover_with_the_drivers_pedal_in_its_window_is_not_in_the_unbraked_deviation(brake_at, unbraked):
    """The handover deviation counts every judged window; its unbraked part only those in which the driver's pedal
    (RunSummary.on_driver_brake) stayed at 0: a pedal from inside the window (0.8 s, 2.0 s) or from before it (0.2 s,
    still on) takes the window out, one after the window's end (2.8 s) does not; the periods held before the pedal
    count as they came (the flush)."""
    j = handover_with_a_dip(RunSummary(DT), brake_at)
    assert j["handover_deviation_pct"] == pytest.approx(25.0)
    assert j["handover_deviation_unbraked_pct"] == (None if unbraked is None else pytest.approx(unbraked))


def test_fault_time_runs_from_each_fault_frame_to_the_next():
    m = CreepMetrics()
    for t, state in ((0.1, 2), (0.2, 5), (0.3, 2), (0.4, 5), (0.5, 5), (0.6, 2)):
        m.status(t, state, 1, 100.0, 100.0, out(t))
    assert m.as_json()["fault_time_s"] == pytest.approx(0.3)


def test_run_summary_json_has_no_sentinels_and_one_wall_time():
    s = RunSummary(dt=DT)
    s.on_step(out(DT), False, False)
    j = s.as_json({"sent": 0, "received": 0, "rejected": 0}, "x", "lockstep", "virtual:x", 1.0)
    text = json.dumps(j, allow_nan=False)
    assert "-1000000000" not in text and "run_wall_time_s" not in j and "wall_time_s" in j
    assert j["speed_error_rms_mps"] is None and j["phases"] == []


# Segments of a record exercising every definition: (seconds, creep requested, outputs)
RECORD = [(1.0, False, {"v": 0.0}), (0.5, True, {"v": -0.04, **CL_SLIPS}), (1.5, True, {"v": 0.0, **CL_SLIPS}),
          (2.03, True, {"v": 0.1, **CL_SLIPS, "T_CL": 249.0, "Q_CL": 1000.0}),
          (0.17, True, {"v": 0.1, **CL_SLIPS, **CH_SLIPS, "M_CH": 100.0}),
          (0.2, True, {"v": 0.1, **CL_SLIPS, **CH_SLIPS, "M_CL": 100.0, "P_CH": 1.2e6}),
          (2.97, True, {"v": 0.12, **CH_SLIPS, "T_CL": 251.0, "T_CH": 250.5, "Q_CH": 3000.0}),
          (1.0, True, {"v": 0.0, **CH_SLIPS}), (0.4, True, {"v": 0.1, "omega_CL": 20.0, "M_CL": float("nan"),
                                                           "P_CL": 0.5e6}),
          (3.0, True, {"v": 0.0, "T_CL": 246.0}), (1.0, False, {"v": 0.0, "T_CL": float("nan")})]


@pytest.mark.parametrize("chunk", [1, 7, 10, 1000])
def test_rows_of_an_array_count_as_samples_one_by_one(chunk):
    """add_rows (the plant's trace of a period) gives what add gives row by row, to the last bit."""
    one, rows = CreepMetrics(), CreepMetrics()
    t, n = 0.0, 0
    for seconds, creep, kw in RECORD:
        samples = []
        for _ in range(round(seconds / DT)):
            drift = {"v": kw["v"] + 1e-4 * math.sin(n), "mu_CH": 0.06 + 1e-5 * n, "P_CL": kw.get("P_CL", 0.0) + n}
            samples.append(out(round(t, 9), **kw | drift))
            one.add(samples[-1], DT, creep, 0.1)
            t, n = t + DT, n + 1
        array = np.array([[float(x) for x in s] for s in samples])
        for lo in range(0, len(array), chunk):
            rows.add_rows(array[lo:lo + chunk], PlantOutputs._fields, lambda r: PlantOutputs(*r.tolist()), DT,
                          creep, 0.1)
    assert json.dumps(rows.as_json()) == json.dumps(one.as_json())
    skip = ("runs", "_rows", "stop", "_rest")
    assert {k: v for k, v in attributes(rows).items() if k not in skip} == {k: v for k, v in attributes(one).items()
                                                                              if k not in skip}
    assert one.stop is not None and rows.stop is not None and rows.stop[0] == one.stop[0]
    assert [(r.clutch, r.start, r.end, r.lagged.t if r.lagged else None) for r in rows.runs] == \
        [(r.clutch, r.start, r.end, r.lagged.t if r.lagged else None) for r in one.runs]


def attributes(obj: object) -> dict[str, object]:
    """An object's attributes by name: ``vars``, or a compiled class's (mypyc: no ``__dict__``; its floats unboxed,
    so a NaN read is a new object, unequal to another: NaN as a string here)."""
    names = getattr(type(obj), "__mypyc_attrs__", None)
    found = vars(obj) if names is None else {name: getattr(obj, name) for name in names}
    return {k: "nan" if isinstance(v, float) and math.isnan(v) else v for k, v in found.items()}


def row_by_row_and_in_blocks(speeds: list[list[float]]) -> tuple[CreepMetrics, CreepMetrics]:
    """The metrics of samples at ``speeds`` (one block per control period), fed with add row by row and with
    add_rows block by block."""
    one, rows = CreepMetrics(), CreepMetrics()
    t = 0.0
    for block in speeds:
        samples = []
        for v in block:
            samples.append(out(round(t, 9), v=v, **CL_SLIPS))
            one.add(samples[-1], DT, True, 0.1)
            t += DT
        rows.add_rows(np.array([[float(x) for x in s] for s in samples]), PlantOutputs._fields,
                      lambda r: PlantOutputs(*r.tolist()), DT, True, 0.1)
    return one, rows


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_rows_with_a_speed_not_finite_count_as_samples_one_by_one(bad):
    """A period's speeds with a NaN or an infinity (Python's floats cannot reduce them as numpy does): add_rows
    still gives what add gives row by row."""
    speeds = [[-0.02, -0.01, 0.05], [0.03, bad, -0.04], [-bad, 0.02, 0.01], [0.04, 0.05, 0.06]]
    one, rows = row_by_row_and_in_blocks(speeds)
    assert json.dumps(rows.as_json()) == json.dumps(one.as_json())
    assert rows.rollback_guarded == one.rollback_guarded > 0.0


def test_roll_back_is_the_backward_displacement_not_the_negative_samples():
    """Issue 16: a held vehicle whose sampled speed alternates sign each sample (ringing at the sampling's Nyquist
    frequency, as the plant's old contact law made it, +-0.89 mm/s) goes nowhere and rolls back nothing; the
    sum of its negative samples (what the summary counted) would be 0.89e-3 * 500 * 0.01 = 4.5 mm in 10 s. A real
    roll-back still counts in full: 1 s at -0.05 m/s, 50 mm (less half a sample at each end of it, the
    trapezoid: the speed steps from and back to zero)."""
    m = CreepMetrics()
    t = 0.0
    for k in range(1000):  # 10 s held, ringing
        m.add(out(round(t, 9), v=0.89e-3 * (-1.0) ** k, **CL_SLIPS), DT, True, 0.1)
        t += DT
    j = m.as_json()
    assert j["rollback_m"] == 0.0 and j["rollback_guarded_m"] == 0.0 and j["rollback_mps"] == pytest.approx(-0.0009)
    t = feed(m, 1.0, t, v=-0.05, **CL_SLIPS)
    feed(m, 1.0, t, v=0.0, **CL_SLIPS)
    j = m.as_json()
    assert j["rollback_m"] == pytest.approx(0.05 - 0.5 * DT * 0.89e-3, abs=1e-4) and j["rollback_mps"] == -0.05
    assert j["rollback_guarded_m"] == j["rollback_m"]


def test_add_rows_counts_the_roll_back_trapezoid_across_periods_as_add_does():
    """The trapezoid spans the periods add_rows is called with (the last speed of one is the first's neighbour),
    the same to the last bit as add row by row."""
    speeds = [[0.02, -0.03, 0.01], [-0.04, -0.01, 0.03], [-0.03, 0.002, -0.001]]
    one, rows = row_by_row_and_in_blocks(speeds)
    flat = [v for block in speeds for v in block]
    back = -sum(min(0.5 * (a + b), 0.0) for a, b in zip([flat[0], *flat[:-1]], flat, strict=True)) * DT
    assert one.rollback_distance == pytest.approx(back, rel=1e-12) and one.rollback_guarded == one.rollback_distance
    assert rows.rollback_distance == one.rollback_distance and rows.rollback_guarded == one.rollback_guarded


@pytest.mark.parametrize("bad", [None, float("nan"), float("inf")])
def test_periods_batched_by_on_period_count_as_samples_one_by_one(bad):
    """RunSummary.on_period holds periods and hands them on in batches (flushed before a TCU_STATUS): the same
    metrics to the last bit as add row by row, a speed that is not finite included (taken period by period)."""
    speeds = [[-0.02, -0.01, 0.05], [0.03, 0.01, -0.04], [-0.03, 0.02, 0.01], [0.04, -0.05, 0.06]] * 3
    if bad is not None:
        speeds[4] = [0.03, bad, -0.04]
        speeds[6] = [-bad, 0.02, 0.01]
    one, batched = CreepMetrics(), RunSummary(DT)
    t, sample = 0.0, lambda r: PlantOutputs(*r.tolist())  # (one function: another is another batch)
    for k, block in enumerate(speeds):
        samples = []
        for v in block:
            samples.append(out(round(t, 9), v=v, **CL_SLIPS))
            one.add(samples[-1], DT, k < 9, 0.1)
            t += DT
        batched.on_period(np.array([[float(x) for x in s] for s in samples]), PlantOutputs._fields, sample, k < 9,
                          False, 0.1)
        if k == 5:  # a TCU_STATUS: FAULT from here (the guarded roll-back counts while creep is not requested)
            status = {"State": 5.0, "ActiveClutch": 1.0, "T_CL_Pred": 90.0, "T_CH_Pred": 80.0}
            batched.on_status(t, status, samples[-1])
            one.status(t, 5.0, 1.0, 90.0, 80.0, samples[-1])
    assert batched._batched > 0  # rows still held, until a flush (as_json flushes)
    batched.flush()
    assert json.dumps(batched.creep.as_json()) == json.dumps(one.as_json())
    assert batched.creep.rollback_guarded == one.rollback_guarded > 0.0
