"""What a run did: the JSON of ``dsg-hil run --summary`` and the creep numbers of ``dsg-hil report``.

One definition for both. :class:`CreepMetrics` takes samples one by one, each with the attributes of
:class:`dsg_hil.physics.plant.PlantOutputs` it needs (SI units; NaN where a quantity is unknown): the plant's outputs
every step for the summary, the frames decoded from a bus log for the report (:mod:`dsg_hil.paper.report.log`).

Definitions (constants below):

* A clutch **slips** when it transmits torque (``|M| > TORQUE_MIN``; without the truth torque on the bus:
  pressure above ``P_ENGAGED``) at a slip speed above ``SLIP_MIN``.
* **Slip time** counts each instant once. During a crossover, when both clutches slip, the instant goes to the
  clutch transmitting the larger torque (the driving one); the crossover itself is ``slip_overlap_s``. So
  ``slip_time_s.CL + slip_time_s.CH`` is the time during which some clutch slips, as in the paper
  (174 s = 43.5 s + 130.5 s).
* **Phases** are the runs of the driving clutch; runs (and gaps) shorter than ``MIN_PHASE_S`` are dropped and
  neighbours of the same clutch merged. A phase's mu and P "at the start" are taken ``SETTLE_S`` after the first
  instant at which its clutch slips alone (the crossover over), "at the end" ``SETTLE_S`` before the last such
  instant (before the next crossover's ramps begin); its temperatures "at the end" at that last instant.
* **Creep time**: the driver requests creep and the vehicle moves forward (``v > V_MOVING``): from the driver's
  request and the vehicle, whatever the TCU reports. **Standstill time**: creep requested, ``|v| <= V_MOVING``.
* **Stop**: the vehicle came to rest (``v <= V_MOVING``) while creep was requested, after creep was under way, and did
  not move again before the request ended or the record ended, resting at least ``STOP_MIN_S``.
* **Roll-back**: the most negative speed, and the distance rolled backwards: the sum of the backward displacements
  between consecutive samples, each the trapezoid of their two speeds (the first sample: its own speed over its
  interval). A speed that alternates sign from one sample to the next about zero (a held vehicle ringing at the
  sampling's Nyquist frequency) moves the vehicle nowhere and adds nothing; a real roll-back adds its distance.
  The lowest speed and the speed error
  while creeping count from the moment creep is under way (``ESTABLISHED`` of the desired speed reached) while
  a clutch slips.
* **Prediction error**: TCU_STATUS predicted plate temperature minus the truth at that time (worst by magnitude).
* **Failures no average hides**: the highest speed and the largest overspeed (speed minus desired speed) while creep
  is requested; the distance rolled backwards while creep is requested or the TCU reports FAULT or
  STOPPED_OVERHEAT (``GUARDED``: the vehicle is the TCU's to hold); the time the TCU reported FAULT (from one
  TCU_STATUS to the next); the smallest margin to ``SAFETY_TEMPERATURE_C`` of the plates (truth) and of the TCU's
  predictions.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from operator import itemgetter
from typing import Protocol

import numpy as np

from ..common.units import CV
from .creep_rows import ACC, Acc, Col, Run, Slot, columns, kernel
from .thresholds import (
    CLUTCHES,
    ESTABLISHED,
    MIN_PHASE_S,
    P_ENGAGED,
    SAFETY_TEMPERATURE_C,
    SETTLE_S,
    SLIP_MIN,
    STATES,
    STOP_MIN_S,
    TORQUE_MIN,
    V_MOVING,
)

__all__ = ["CLUTCHES", "ESTABLISHED", "MIN_PHASE_S", "P_ENGAGED", "SAFETY_TEMPERATURE_C", "SETTLE_S", "SLIP_MIN",
           "STATES", "STOP_MIN_S", "TORQUE_MIN", "V_MOVING",  # re-exported: the metrics' definitions
           "GUARDED", "CreepMetrics", "RunSummary", "Sample", "driving_clutch", "phases"]

BATCH_ROWS = 256  # RunSummary.on_period: rows held for one CreepMetrics.add_rows call, at most
GUARDED = ("FAULT", "STOPPED_OVERHEAT")  # TCU states in which the vehicle's roll-back counts as the TCU's
HANDOVER_AFTER_S = 1.0  # a handover's speed is judged through the crossover and this long after it
HANDOVER_BAND = 0.2  # ... if it began with the speed within this fraction of the desired speed (the drivability band)
_IN_ACC_ORDER = itemgetter(*ACC)  # values by accumulator name -> the tuple in the order of creep_rows' acc
_ACC_UNPACKED = ("slip_CL", "slip_CH", "overlap", "max_T_CL", "max_T_CH", "above_CL", "above_CH", "energy_CL",
                 "energy_CH", "rollback_speed", "rollback_distance", "creep", "standstill", "moved", "sq_speed_error",
                 "driven_time", "speed_min", "t_last", "resting", "rest_row", "v_prev")  # add_rows unpacks acc so
_RESTING, _REST_ROW = int(Acc.resting), int(Acc.rest_row)  # (plain ints index numpy faster than an IntEnum)
if ACC != _ACC_UNPACKED:
    raise ImportError(f"creep_rows.Acc is {ACC}, CreepMetrics.add_rows unpacks {_ACC_UNPACKED}")


class Sample(Protocol):
    """What :class:`CreepMetrics` reads of a sample: these attributes of :class:`dsg_hil.physics.plant.PlantOutputs`
    (:class:`dsg_hil.paper.report.log.LogSample` has them too)."""

    @property
    def t(self) -> float: ...

    @property
    def v(self) -> float: ...

    @property
    def omega_in(self) -> float: ...

    @property
    def omega_CL(self) -> float: ...

    @property
    def omega_CH(self) -> float: ...

    @property
    def P_CL(self) -> float: ...

    @property
    def P_CH(self) -> float: ...

    @property
    def T_CL(self) -> float: ...

    @property
    def T_CH(self) -> float: ...

    @property
    def mu_CL(self) -> float: ...

    @property
    def mu_CH(self) -> float: ...

    @property
    def M_CL(self) -> float: ...

    @property
    def M_CH(self) -> float: ...

    @property
    def Q_CL(self) -> float: ...

    @property
    def Q_CH(self) -> float: ...


def _known(x: float) -> bool:
    return x == x  # not NaN


def _slips(omega_in: float, omega: float, M: float, P: float) -> bool:
    """Transmits torque (or, with no torque known, is pressurised) while slipping."""
    return (abs(M) > TORQUE_MIN if M == M else P > P_ENGAGED) and abs(omega_in - omega) > SLIP_MIN


def driving_clutch(s: Sample) -> tuple[str | None, bool]:
    """The slipping clutch that drives (the larger torque when both slip), and whether both slip."""
    cl = _slips(s.omega_in, s.omega_CL, s.M_CL, s.P_CL)
    ch = _slips(s.omega_in, s.omega_CH, s.M_CH, s.P_CH)
    if cl and ch:
        a, b = (abs(s.M_CL), abs(s.M_CH)) if _known(s.M_CL) and _known(s.M_CH) else (s.P_CL, s.P_CH)
        return ("CL" if a >= b else "CH"), True
    return ("CL" if cl else "CH" if ch else None), False


@dataclass(frozen=True)
class _Status:
    """A TCU_STATUS frame awaiting the next one's confirmation: its time, state names, predictions and the truth."""

    t: float
    state: str
    clutch: str
    T_CL_pred: float
    T_CH_pred: float
    truth: Sample


@dataclass
class _Run:
    """A run of one driving clutch (None: none slips). Samples at which it slips alone: the first, the one
    SETTLE_S later, the one SETTLE_S before the last, the last."""

    clutch: str | None
    start: float
    end: float
    first: Sample | None = None
    settled: Sample | None = None
    lagged: Sample | None = None
    last: Sample | None = None
    tail: Sample | None = None  # last sample of the run
    window: deque[Sample] = field(default_factory=deque)

    def values(self) -> tuple[Sample, Sample, Sample]:
        """(start, end, last) samples: the start and end values of mu and P, and the temperatures at the end."""
        last = self.last or self.tail
        start = self.settled or self.first or self.tail
        assert start is not None and last is not None, "a run is created with its first sample"
        return start, self.lagged or last, last


def _moved(prev: float, v: float) -> float:
    """The mean speed between the last sample's speed ``prev`` (NaN: none) and this one's ``v``, by the trapezoid
    rule: what the vehicle moved since the last sample, per unit time (module docstring, roll-back)."""
    return 0.5 * (v + (v if prev != prev else prev))


def _in_order(total: float, terms: np.ndarray) -> float:
    """``total`` plus ``terms`` added one by one, left to right (as a loop would: np.cumsum is sequential)."""
    if not len(terms):
        return total
    return float(np.cumsum(np.concatenate(([total], terms)))[-1])


@dataclass
class _Rows:
    """The state of :meth:`CreepMetrics.add_rows` (see :mod:`dsg_hil.results.creep_rows`): the columns it reads, how a
    row becomes a sample, the open run (Run, Slot) and its window of rows (a ring)."""

    fields: tuple[str, ...]
    cols: np.ndarray
    sample: Callable[[np.ndarray], Sample]
    dt: float
    run: np.ndarray
    slots: np.ndarray
    ring: np.ndarray
    ring_t: np.ndarray
    step: Callable[..., int]  # the compiled creep_rows
    v_col: int  # the column of the vehicle speed
    open: bool = False  # the last of CreepMetrics.runs is this run
    acc: np.ndarray | None = None  # the accumulators (:meth:`CreepMetrics._accumulators`), kept from call to call


def _margin(peaks: dict[str, float | None]) -> float | None:
    """SAFETY_TEMPERATURE_C minus the higher of the two peaks [K] (None: neither known)."""
    known = [T for T in peaks.values() if T is not None]
    return _r(SAFETY_TEMPERATURE_C - max(known), 2) if known else None


def _r(x: float | None, nd: int) -> float | None:
    return None if x is None or not math.isfinite(x) else round(x, nd) + 0.0  # no -0.0


def _phase_json(run: _Run) -> dict:
    c = run.clutch
    a, b, last = run.values()
    return {"clutch": c, "start_s": round(run.start, 3), "end_s": round(run.end, 3),
            "duration_s": round(run.end - run.start, 3),
            "T_CL_end_c": _r(last.T_CL, 2), "T_CH_end_c": _r(last.T_CH, 2),
            "mu": {"start": _r(getattr(a, f"mu_{c}"), 4), "end": _r(getattr(b, f"mu_{c}"), 4)},
            "P_mpa": {"start": _r(getattr(a, f"P_{c}") / CV.MPA_TO_PA, 3),
                      "end": _r(getattr(b, f"P_{c}") / CV.MPA_TO_PA, 3)}}


def phases(runs: list[_Run]) -> list[_Run]:
    """Runs of the driving clutch without the short ones, neighbours of the same clutch merged."""
    kept: list[_Run] = []
    for run in runs:
        if run.end - run.start < MIN_PHASE_S:
            continue
        if kept and kept[-1].clutch == run.clutch:
            prev = kept[-1]
            kept[-1] = _Run(run.clutch, prev.start, run.end, prev.first or run.first, prev.settled or run.settled,
                            run.lagged or prev.lagged, run.last or prev.last, run.tail)
        else:
            kept.append(run)
    return [r for r in kept if r.clutch is not None]


@dataclass
class CreepMetrics:
    """Accumulates a creep run sample by sample (see the module docstring for the definitions)."""

    slip_time: dict[str, float] = field(default_factory=lambda: {"CL": 0.0, "CH": 0.0})
    slip_overlap: float = 0.0
    creep_time: float = 0.0
    standstill_time: float = 0.0
    above_limit: dict[str, float] = field(default_factory=lambda: {"CL": 0.0, "CH": 0.0})
    energy: dict[str, float] = field(default_factory=lambda: {"CL": 0.0, "CH": 0.0})  # J
    max_T: dict[str, float | None] = field(default_factory=lambda: {"CL": None, "CH": None})
    speed_min_creeping: float | None = None
    rollback_speed: float = 0.0
    rollback_distance: float = 0.0
    stop: tuple[float, Sample] | None = None
    # from TCU_STATUS, when a TCU sends it
    handovers: list[dict] = field(default_factory=list)
    tcu_state: str | None = None
    active_clutch: str | None = None
    tcu_stop_s: float | None = None
    max_pred: dict[str, float | None] = field(default_factory=lambda: {"CL": None, "CH": None})
    pred_error: dict[str, tuple[float, float] | None] = field(default_factory=lambda: {"CL": None, "CH": None})
    runs: list[_Run] = field(default_factory=list)
    max_speed_creep: float | None = None  # highest speed while creep is requested
    overspeed: float | None = None  # largest speed minus desired speed while creep is requested
    rollback_guarded: float = 0.0  # distance rolled backwards while creep is requested or the TCU is in GUARDED
    fault_time: float = 0.0  # time TCU_STATUS reported FAULT
    status_unconfirmed: int = 0  # TCU_STATUS frames whose stop or active clutch the next one did not confirm
    handover_deviation: float | None = None  # worst |v - desired| / desired through handovers begun in the band
    handover_deviation_unbraked: float | None = None  # ... through those in whose window the driver's pedal stayed 0
    driver_braking: bool = False  # the driver's pedal above 0 now (RunSummary.on_driver_brake)
    _handover_until: float = -math.inf  # the handover window's end (inf: HANDOVER reported now)
    _handover_judged: bool | None = None  # this window: None not yet decided, False begun outside the band
    _handover_pending: float | None = None  # this window's worst so far: taken when it ends in CREEP
    _handover_desired: float = math.nan  # the desired speed the window began with
    _handover_braked: bool = False  # the driver's pedal was above 0 in this window, while it was judged
    _status_t: float | None = None  # time of the last TCU_STATUS
    _clutch: str | None = None  # the active clutch as the record took it (confirmed)
    _held: _Status | None = None  # the latest TCU_STATUS: its stop and clutch confirmed or not by the next one
    _sq_speed_error: float = 0.0
    _driven_time: float = 0.0
    _moved: bool = False
    _rest: tuple[float, Sample] | None = None
    _t_last: float = 0.0
    _v_prev: float = math.nan  # the last sample's speed (NaN: none yet): the roll-back's trapezoid
    _rows: _Rows | None = None  # add_rows: its compiled code's state

    def add(self, s: Sample, dt: float, creep_request: bool, desired_speed: float) -> None:
        """One sample ``s`` standing for the interval [s.t, s.t + dt) (real time; lock-step feeds whole periods
        through :meth:`add_rows`)."""
        if self._rows is not None:  # (add_rows' accumulators are read from the attributes again)
            self._rows.acc = None
        clutch, both = driving_clutch(s)
        t = s.t
        if clutch is not None:
            self.slip_time[clutch] += dt
            self.slip_overlap += dt if both else 0.0
        runs = self.runs
        if not runs or runs[-1].clutch != clutch:
            runs.append(_Run(clutch, t, t))
        run = runs[-1]
        run.end, run.tail = t + dt, s
        if clutch is not None and not both:
            if run.first is None:
                run.first = s
            if run.settled is None and t >= run.first.t + SETTLE_S - 1e-9:
                run.settled = s
            window = run.window
            window.append(s)
            while window[0].t <= t - SETTLE_S + 1e-9:
                run.lagged = window.popleft()
            run.last = s
        for name, T, Q in (("CL", s.T_CL, s.Q_CL), ("CH", s.T_CH, s.Q_CH)):
            if T == T:
                peak = self.max_T[name]
                if peak is None or T > peak:
                    self.max_T[name] = T
                if T > SAFETY_TEMPERATURE_C:
                    self.above_limit[name] += dt
            if Q == Q:
                self.energy[name] += Q * dt
        v = s.v
        if v < 0.0:
            self.rollback_speed = min(self.rollback_speed, v)
        moved = _moved(self._v_prev, v)
        self._v_prev = v
        if moved < 0.0:
            self.rollback_distance -= moved * dt
            if creep_request or self.tcu_state in GUARDED:
                self.rollback_guarded -= moved * dt
        if creep_request:
            self._creep_speed(v, v, v, desired_speed)
        if not creep_request:
            self._end_rest()
            return
        if v > V_MOVING:
            self.creep_time += dt
            self._rest = None
            self._moved = self._moved or v >= ESTABLISHED * desired_speed
        else:
            if abs(v) <= V_MOVING:
                self.standstill_time += dt
            if self._moved and self._rest is None:
                self._rest = (t, s)
        if self._moved and clutch is not None:
            self._sq_speed_error += (v - desired_speed) ** 2 * dt
            self._driven_time += dt
            self.speed_min_creeping = v if self.speed_min_creeping is None else min(self.speed_min_creeping, v)
        self._t_last = t + dt

    @staticmethod
    def prepare() -> None:
        """Load :meth:`add_rows`' compiled code now (numba's cache; seconds under emulation) rather than at its
        first call, in the middle of a run."""
        kernel()

    def add_rows(self, rows: np.ndarray, fields: Sequence[str], sample: Callable[[np.ndarray], Sample], dt: float,
                 creep_request: bool, desired_speed: float, period: int | None = None) -> None:
        """Consecutive samples as the rows of an array (columns named by ``fields``), ``creep_request`` and
        ``desired_speed`` held over them: :meth:`add` on each row in turn, compiled
        (:func:`dsg_hil.results.creep_rows.creep_rows`, the same operations, so the same sums to the last bit).
        ``sample``
        makes a :class:`Sample` of a row, for the rows a run keeps. A record is taken either by :meth:`add` or
        by this, not both. ``period``: the rows are periods of that many rows, each as a call of its own would
        take it (the same result; a batch of periods costs one call, :meth:`RunSummary.on_period`)."""
        n = len(rows)
        if n == 0:
            return
        rows = np.ascontiguousarray(rows, dtype=np.float64)
        st = self._rows
        if st is None or st.fields != tuple(fields) or st.dt != dt:
            self._materialise()
            cap = int(SETTLE_S / dt) + 8  # the window: the samples of the last SETTLE_S and the new one
            fields = tuple(fields)
            st = self._rows = _Rows(fields, columns(fields), sample, dt, np.zeros(len(Run)),
                                    np.zeros((len(Slot), rows.shape[1])), np.zeros((cap, rows.shape[1])),
                                    np.zeros(cap), kernel(), fields.index("v"))
            st.run[Run.code] = -1.0  # no run open
        v = rows[:, st.v_col].tolist()  # (a period's few rows: Python's floats cost less than numpy's calls)
        total = sum(v)
        if period is not None and period < n and total != total:  # a NaN: period by period, as separate calls
            prev = self._v_prev
            for lo in range(0, n, period):
                part = v[lo:lo + period]
                self._guarded_and_speed(part, sum(part), rows[lo:lo + period, st.v_col], prev, dt, creep_request,
                                        desired_speed)
                prev = part[-1]
        else:  # (no NaN in the whole, none in a period: the sums, in order, and the maxima are the periods')
            self._guarded_and_speed(v, total, rows[:, st.v_col], self._v_prev, dt, creep_request, desired_speed)
        # the accumulators stay in their array from one call to the next (only this method and the rest's end
        # change them between calls); the attributes are written from it after each call
        acc = st.acc
        if acc is None:
            acc = st.acc = self._accumulators()
        else:
            acc[_RESTING], acc[_REST_ROW] = (0.0 if self._rest is None else 1.0), -1.0
        step, k, creep = st.step, 0, 1.0 if creep_request else 0.0
        while (k := step(rows, k, st.cols, dt, creep, desired_speed, acc, st.run, st.slots, st.ring,
                         st.ring_t)) < n:
            self._materialise()  # the driving clutch changes at row k: its run starts there
            st.run[Run.end:] = 0.0
            t = float(rows[k, st.cols[Col.t]])
            self.runs.append(_Run(CLUTCHES.get(int(st.run[Run.code])), t, t))
            st.open = True
        (slip_CL, slip_CH, self.slip_overlap, max_T_CL, max_T_CH, above_CL, above_CH, energy_CL, energy_CH,
         self.rollback_speed, self.rollback_distance, creep_time, standstill, moved, sq_speed_error, driven_time,
         speed_min, t_last, resting, rest_row, self._v_prev) = acc.tolist()  # in the order of Acc (_ACC_UNPACKED)
        self.slip_time["CL"], self.slip_time["CH"] = slip_CL, slip_CH
        self.max_T["CL"] = None if max_T_CL != max_T_CL else max_T_CL
        self.max_T["CH"] = None if max_T_CH != max_T_CH else max_T_CH
        self.above_limit["CL"], self.above_limit["CH"] = above_CL, above_CH
        self.energy["CL"], self.energy["CH"] = energy_CL, energy_CH
        if not creep_request:  # (the compiled code leaves the creep's accumulators alone without the request)
            self._end_rest()
            return
        self.creep_time, self.standstill_time, self._moved = creep_time, standstill, moved != 0.0
        self._sq_speed_error, self._driven_time, self._t_last = sq_speed_error, driven_time, t_last
        self.speed_min_creeping = None if speed_min != speed_min else speed_min
        if resting == 0.0:
            self._rest = None
        elif rest_row >= 0.0:
            row = rows[int(rest_row)]
            self._rest = (float(row[st.cols[Col.t]]), sample(row))

    def _guarded_and_speed(self, v: list[float], total: float, speeds: np.ndarray, prev: float, dt: float,
                           creep_request: bool, desired_speed: float) -> None:
        """:meth:`add_rows`' roll-back while guarded and highest creep speed of the speeds ``v`` (their sum
        ``total``; ``speeds``, as an array; ``prev``: the speed before them)."""
        if total != total:  # a NaN (or infinities of both signs): numpy's reductions, as they treat it
            self._rollback_and_speed(speeds, prev, dt, creep_request, desired_speed)
            return
        if (min(v) < 0.0 or prev < 0.0) and (creep_request or self.tcu_state in GUARDED):
            guarded = self.rollback_guarded
            for x in v:  # as add: the trapezoid since the last sample, row by row
                moved = _moved(prev, x)
                prev = x
                if moved < 0.0:
                    guarded -= moved * dt
            self.rollback_guarded = guarded
        if creep_request:
            self._creep_speed(v[0], min(v), max(v), desired_speed)

    def _rollback_and_speed(self, v: np.ndarray, v_prev: float, dt: float, creep_request: bool,
                            desired_speed: float) -> None:
        """:meth:`add_rows`' roll-back while guarded and highest creep speed, by numpy's reductions (speeds ``v``
        with a NaN, ``v_prev`` the speed before them)."""
        if creep_request or self.tcu_state in GUARDED:
            prev = np.concatenate(([v_prev], v[:-1]))
            moved = 0.5 * (v + np.where(prev != prev, v, prev))  # as add: the trapezoid since the last sample
            back = moved[moved < 0.0]
            if len(back):
                self.rollback_guarded = _in_order(self.rollback_guarded, -back * dt)  # as add, row by row
        if creep_request:
            self._creep_speed(float(v[0]), float(v.min()), float(v.max()), desired_speed)

    def _handover_speed(self, v_first: float, v_min: float, v_max: float, desired_speed: float) -> None:
        """Creep requested at speeds from ``v_min`` to ``v_max`` (the first ``v_first``): inside a handover's window
        (the TCU reporting HANDOVER, and HANDOVER_AFTER_S after while it reports CREEP) that began with the speed
        within HANDOVER_BAND of the desired speed, the worst deviation from it; counted when the window ends in
        CREEP (:meth:`_take_handover`). Not judged: a handover begun during a launch's ramp, or one whose window a
        stop, a fault, the driver's brake, the creep withdrawn or a new desired speed interrupts (the speed then is
        not the handover's). A window in which the driver's pedal is above 0 (a light drag, under the TCU's "pressed"
        threshold, leaves it in CREEP) counts in the handover deviation, not in its unbraked part."""
        if self._status_t is None or self._status_t > self._handover_until or not desired_speed > 0.0:
            return
        if self._handover_judged is None:
            self._handover_judged = abs(v_first - desired_speed) <= HANDOVER_BAND * desired_speed
            self._handover_desired = desired_speed
        elif desired_speed != self._handover_desired:  # a new desired speed: the speed follows its ramp, not judged
            self._handover_judged, self._handover_pending, self._handover_braked = False, None, False
        if self._handover_judged:
            if self.driver_braking:
                self._handover_braked = True
            worst = max(v_max - desired_speed, desired_speed - v_min) / desired_speed
            if worst == worst and (self._handover_pending is None or worst > self._handover_pending):
                self._handover_pending = worst

    def _take_handover(self) -> None:
        """The window's worst deviation counts: it ended in CREEP (or the record ended); in the unbraked deviation
        too if the driver's pedal stayed at 0 through it."""
        worst, braked, self._handover_pending, self._handover_braked = self._handover_pending, self._handover_braked, \
            None, False
        if worst is None:
            return
        if self.handover_deviation is None or worst > self.handover_deviation:
            self.handover_deviation = worst
        if not braked and (self.handover_deviation_unbraked is None or worst > self.handover_deviation_unbraked):
            self.handover_deviation_unbraked = worst

    def _creep_speed(self, v_first: float, v_min: float, v_max: float, desired_speed: float) -> None:
        """Creep requested at speeds from ``v_min`` to ``v_max`` [m/s] (the first ``v_first``): the highest speed and
        overspeed, and the speed through a handover (:meth:`_handover_speed`)."""
        if self.max_speed_creep is None or v_max > self.max_speed_creep:
            self.max_speed_creep = v_max
        over = v_max - desired_speed
        if self.overspeed is None or over > self.overspeed:
            self.overspeed = over
        self._handover_speed(v_first, v_min, v_max, desired_speed)

    def _accumulators(self) -> np.ndarray:
        """The state the compiled code accumulates into, as its ``acc``: by the names of
        :class:`dsg_hil.results.creep_rows.Acc` (None as NaN)."""
        nan = math.nan
        state = {"slip_CL": self.slip_time["CL"], "slip_CH": self.slip_time["CH"], "overlap": self.slip_overlap,
                 "max_T_CL": nan if self.max_T["CL"] is None else self.max_T["CL"],
                 "max_T_CH": nan if self.max_T["CH"] is None else self.max_T["CH"],
                 "above_CL": self.above_limit["CL"], "above_CH": self.above_limit["CH"],
                 "energy_CL": self.energy["CL"], "energy_CH": self.energy["CH"],
                 "rollback_speed": self.rollback_speed, "rollback_distance": self.rollback_distance,
                 "creep": self.creep_time, "standstill": self.standstill_time, "moved": float(self._moved),
                 "sq_speed_error": self._sq_speed_error, "driven_time": self._driven_time,
                 "speed_min": nan if self.speed_min_creeping is None else self.speed_min_creeping,
                 "t_last": self._t_last, "resting": float(self._rest is not None), "rest_row": -1.0,
                 "v_prev": self._v_prev}
        return np.array(_IN_ACC_ORDER(state))

    def _materialise(self) -> None:
        """The open run of :meth:`add_rows` (kept as rows by the compiled code) as samples on its _Run."""
        st = self._rows
        if st is None or not st.open:
            return
        run, state, make = self.runs[-1], st.run.tolist(), st.sample
        run.end, run.tail = state[Run.end], make(st.slots[Slot.tail])
        run.first = make(st.slots[Slot.first]) if state[Run.has_first] else None
        run.settled = make(st.slots[Slot.settled]) if state[Run.has_settled] else None
        run.lagged = make(st.slots[Slot.lagged]) if state[Run.has_lagged] else None
        run.last = make(st.slots[Slot.last]) if state[Run.has_last] else None

    def _end_rest(self) -> None:
        if self._rest is not None and self.stop is None and self._t_last - self._rest[0] >= STOP_MIN_S:
            self.stop = self._rest
        self._rest = None

    def status(self, t: float, state: float, active: float, T_CL_pred: float, T_CH_pred: float,
               truth: Sample) -> None:
        """A TCU_STATUS frame at ``t`` (raw State/ActiveClutch values), with the truth at that time.

        Its state, the time in FAULT and the predictions count at once. A stop (STOPPED_OVERHEAT) and a change of
        the active clutch (a handover) are states the TCU holds, never a single frame: the record takes them when
        the next frame confirms them (or the record ends), dated at their first frame. A random frame with
        TCU_STATUS's ID passes the CRC (1 in 256) and the counter (3 in 16) once in ~1,400 (a frame flood); taken,
        it could end the creep with a stop the TCU never made. Such frames are counted in
        ``status_unconfirmed``."""
        frame = _Status(t, STATES.get(int(state), f"UNKNOWN_{int(state)}"), CLUTCHES.get(int(active), "NONE"),
                        T_CL_pred, T_CH_pred, truth)
        if self.tcu_state == "FAULT" and self._status_t is not None:
            self.fault_time += t - self._status_t
        self._status_t = t
        if frame.state == "HANDOVER":
            if self._handover_until != math.inf:  # a new window
                self._take_handover()
                self._handover_until, self._handover_judged = math.inf, None
        elif frame.state != "CREEP":  # a stop, a fault, the driver's brake or the creep withdrawn: not judged
            self._handover_until, self._handover_pending, self._handover_braked = -math.inf, None, False
        elif self._handover_until == math.inf:
            self._handover_until = t + HANDOVER_AFTER_S
        elif t > self._handover_until:
            self._take_handover()
        self.tcu_state, self.active_clutch = frame.state, frame.clutch
        held, self._held = self._held, frame
        if held is not None:
            self._confirm(held, frame)
        for name, pred, true in (("CL", T_CL_pred, truth.T_CL), ("CH", T_CH_pred, truth.T_CH)):
            peak, worst = self.max_pred[name], self.pred_error[name]
            if peak is None or pred > peak:
                self.max_pred[name] = pred
            if _known(true):
                err = pred - true
                if worst is None or abs(err) > abs(worst[0]):
                    self.pred_error[name] = (err, t)

    def _confirm(self, frame: _Status, after: _Status | None) -> None:
        """Take ``frame``'s stop and active clutch if ``after`` (the next frame; None: the record ends there, and
        nothing refutes it) reports them too; the first frame's clutch at once."""
        clutch, before = frame.clutch, self._clutch
        unconfirmed = False
        if frame.state == "STOPPED_OVERHEAT" and self.tcu_stop_s is None:
            if after is None or after.state == frame.state:
                self.tcu_stop_s = round(frame.t, 3)
            else:
                unconfirmed = True
        if clutch != before:
            if before is None or after is None or after.clutch == clutch:  # (the first frame: no change to confirm)
                self._clutch = clutch
                if clutch in ("CL", "CH") and before in ("CL", "CH"):
                    truth = frame.truth
                    self.handovers.append({"t_s": round(frame.t, 3), "from": before, "to": clutch,
                                           "T_CL_c": _r(truth.T_CL, 2), "T_CH_c": _r(truth.T_CH, 2),
                                           "T_CL_pred_c": round(frame.T_CL_pred, 1),
                                           "T_CH_pred_c": round(frame.T_CH_pred, 1)})
            else:
                unconfirmed = True
        self.status_unconfirmed += unconfirmed

    def as_json(self) -> dict:
        self._materialise()
        self._end_rest()  # the record ends: a vehicle resting since long enough has stopped
        if self._held is not None:  # the record ends: its last TCU_STATUS has no frame after it
            self._confirm(self._held, None)
            self._held = None
        self._take_handover()
        ph = phases(self.runs)
        first_ch = next((p for p in ph if p.clutch == "CH"), None)
        stop_t, stop_s = self.stop if self.stop is not None else (None, None)
        both = lambda d, nd: {k: _r(v, nd) for k, v in d.items()}  # noqa: E731
        if self.tcu_stop_s is not None:
            reason = "STOPPED_OVERHEAT"
        else:
            reason = "vehicle_stopped" if stop_t is not None else "end_of_record"
        return {
            "creep_time_s": round(self.creep_time, 3),
            "standstill_time_s": round(self.standstill_time, 3),
            "slip_time_s": both(self.slip_time, 3),
            "slip_overlap_s": round(self.slip_overlap, 3),
            "phases": [_phase_json(p) for p in ph],
            "max_plate_temp_c": both(self.max_T, 2),
            "time_above_limit_s": both(self.above_limit, 3),
            "friction_energy_kj": {k: round(v / CV.KJ_TO_J, 1) for k, v in self.energy.items()},
            "speed_min_creeping_mps": _r(self.speed_min_creeping, 4),
            "rollback_mps": round(self.rollback_speed, 4),
            "rollback_m": round(self.rollback_distance, 4),
            "speed_error_rms_mps": _r(math.sqrt(self._sq_speed_error / self._driven_time), 4)
            if self._driven_time > 0 else None,
            "stop_reason": reason,
            "stop_time_s": _r(stop_t, 3),
            "tcu_stop_time_s": self.tcu_stop_s,
            "T_CL_at_stop_c": None if stop_s is None else _r(stop_s.T_CL, 2),
            "T_CL_at_first_CH_limit_c": None if first_ch is None else _r(first_ch.values()[2].T_CL, 2),
            "mu_CH_first_slip": None if first_ch is None else _phase_json(first_ch)["mu"],
            "P_CH_first_slip_mpa": None if first_ch is None else _phase_json(first_ch)["P_mpa"],
            "max_predicted_temp_c": both(self.max_pred, 1),
            "worst_prediction_error_c": {k: None if e is None else {"error_c": round(e[0], 2), "t_s": round(e[1], 3)}
                                         for k, e in self.pred_error.items()},
            "handovers": self.handovers,
            "max_speed_creep_mps": _r(self.max_speed_creep, 4),
            "overspeed_mps": _r(self.overspeed, 4),
            "rollback_guarded_m": round(self.rollback_guarded, 4),
            "fault_time_s": round(self.fault_time, 3),
            "min_margin_c": {"truth": _margin(self.max_T), "predicted": _margin(self.max_pred)},
            "status_unconfirmed": self.status_unconfirmed,
            "handover_deviation_pct": _r(None if self.handover_deviation is None else 100.0 * self.handover_deviation,
                                         1),
            "handover_deviation_unbraked_pct": _r(None if self.handover_deviation_unbraked is None
                                                  else 100.0 * self.handover_deviation_unbraked, 1),
        }


@dataclass
class RunSummary:
    """A run of the plant: the creep metrics of its steps and TCU_STATUS frames, and the run's bookkeeping."""

    dt: float
    creep: CreepMetrics = field(default_factory=CreepMetrics)
    fallback_events: int = 0
    fallback_time_s: float = 0.0
    realtime_factor: float | None = None  # simulated s per wall s of a real-time run
    wall_time_s: float | None = None  # of the run itself (after the lockstep handshake)
    command_latency_s: list[float] = field(default_factory=list)  # real time: TCU_CMD on the bus -> used
    stop_reason: str | None = None  # ended early: interrupted, terminated, peer_lost, no_peer; else the creep's
    # on_period's rows not yet in ``creep`` (see flush): a copy of them, how many, and what they were given with
    _batch: np.ndarray | None = field(default=None, repr=False, compare=False)
    _batched: int = field(default=0, repr=False, compare=False)
    _batch_args: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def tcu_state(self) -> str:
        return self.creep.tcu_state or "IDLE"

    @property
    def active_clutch(self) -> str:
        return self.creep.active_clutch or "NONE"

    def on_step(self, out: Sample, creeping: bool, fallback: bool, desired_speed: float = 0.0) -> None:
        """One plant step: ``out`` holds the outputs at its end, and stands for the step just taken."""
        self.flush()
        self.creep.add(out, self.dt, creeping, desired_speed)
        if fallback:
            self.fallback_time_s += self.dt

    def on_period(self, rows: np.ndarray, fields: Sequence[str], sample: Callable[[np.ndarray], Sample],
                  creeping: bool, fallback: bool, desired_speed: float = 0.0) -> None:
        """Plant steps as the rows of an array (:meth:`CreepMetrics.add_rows`): :meth:`on_step` on each row. The rows
        are copied and handed on in batches of periods (:meth:`flush`): one call for up to ``BATCH_ROWS`` rows given
        with the same arguments, the same sums to the last bit."""
        n, args = len(rows), (fields, sample, creeping, desired_speed, len(rows))
        batch, k = self._batch, self._batched
        if k and batch is not None and (args != self._batch_args or k + n > len(batch)
                                        or batch.shape[1] != rows.shape[1]):
            self.flush()
            k = 0
        if batch is None or batch.shape[1] != rows.shape[1] or n > len(batch):
            batch = self._batch = np.empty((max(BATCH_ROWS, n), rows.shape[1]))
        batch[k:k + n] = rows
        self._batched, self._batch_args = k + n, args
        if fallback:
            self.fallback_time_s = _in_order(self.fallback_time_s, np.full(len(rows), self.dt))

    def flush(self) -> None:
        """Hand the rows :meth:`on_period` holds to ``creep`` (:meth:`CreepMetrics.add_rows`); done before a
        TCU_STATUS is taken (the guarded roll-back depends on the TCU's state), a single step, and the summary."""
        k = self._batched
        if k:
            assert self._batch is not None and self._batch_args is not None
            fields, sample, creeping, desired_speed, period = self._batch_args
            self._batched = 0
            self.creep.add_rows(self._batch[:k], fields, sample, self.dt, creeping, desired_speed, period)

    def on_driver_brake(self, braking: bool) -> None:
        """The driver's pedal went above 0 (``braking``) or back to 0, from the next plant step on (the steps before,
        still held, are taken first): for the handover deviation's unbraked part."""
        self.flush()
        self.creep.driver_braking = braking

    def on_status(self, t: float, values: dict[str, float], truth: Sample) -> None:
        self.flush()
        self.creep.status(t, values["State"], values["ActiveClutch"], values["T_CL_Pred"], values["T_CH_Pred"],
                          truth)

    def as_json(self, frames: dict[str, int], scenario: str, mode: str, interface: str, duration_s: float) -> dict:
        self.flush()
        creep = self.creep.as_json()
        if self.stop_reason is not None:
            creep["stop_reason"] = self.stop_reason
        return {
            "scenario": scenario, "mode": mode, "interface": interface, "duration_s": round(duration_s, 3),
            **creep,
            "command_fallback": {"events": self.fallback_events, "time_s": round(self.fallback_time_s, 3)},
            "frames": frames,
            "realtime_factor": None if self.realtime_factor is None else round(self.realtime_factor, 3),
            "wall_time_s": None if self.wall_time_s is None else round(self.wall_time_s, 3),
            "command_latency_ms": _percentiles(self.command_latency_s),
        }


def _percentiles(samples: list[float]) -> dict | None:
    if not samples:
        return None
    s = sorted(samples)
    pick = lambda q: s[min(len(s) - 1, int(q * (len(s) - 1) + 0.5))]  # noqa: E731
    ms = CV.S_TO_MS
    return {"n": len(s), "p50": round(ms * pick(0.5), 3), "p99": round(ms * pick(0.99), 3), "max": round(ms * s[-1], 3)}
