"""The per-step part of :meth:`dsg_hil.results.summary.CreepMetrics.add`, compiled, over the rows of a plant trace.

:func:`creep_rows` runs the same operations as ``CreepMetrics.add`` on each row in turn (so its sums and extremes
are the same to the last bit) and keeps the open run of the driving clutch as rows (:class:`Slot`, and the window of
the samples at which its clutch slips alone, a ring of rows): Python makes samples of rows only when a run ends (the
kernel returns there) and when a rest starts. Its arrays are addressed by name: :class:`Col`, :class:`Acc`,
:class:`Run`, :class:`Slot`.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from ..physics.jit import compiled
from .thresholds import ESTABLISHED, P_ENGAGED, SAFETY_TEMPERATURE_C, SETTLE_S, SLIP_MIN, TORQUE_MIN, V_MOVING

__all__ = ["ACC", "COLUMNS", "RUN", "SLOTS", "Acc", "Col", "Run", "Slot", "columns", "creep_rows", "kernel"]


# The kernel's arrays, addressed by name (numba reads an IntEnum member as its integer): each class lists its
# entries in array order, numbered 0, 1, 2 ... (a test checks).
class Col(IntEnum):
    """The columns :func:`creep_rows` reads (``cols[Col.v]``: where the rows hold the vehicle speed)."""

    t = 0
    v = 1
    omega_in = 2
    omega_CL = 3
    omega_CH = 4
    P_CL = 5
    P_CH = 6
    T_CL = 7
    T_CH = 8
    M_CL = 9
    M_CH = 10
    Q_CL = 11
    Q_CH = 12


class Acc(IntEnum):
    """The accumulators ``acc``: the state of :class:`dsg_hil.results.summary.CreepMetrics` (NaN: None)."""

    slip_CL = 0  # slip_time["CL"]
    slip_CH = 1
    overlap = 2  # slip_overlap
    max_T_CL = 3  # max_T["CL"]
    max_T_CH = 4
    above_CL = 5  # above_limit["CL"]
    above_CH = 6
    energy_CL = 7  # energy["CL"]
    energy_CH = 8
    rollback_speed = 9
    rollback_distance = 10
    creep = 11  # creep_time
    standstill = 12  # standstill_time
    moved = 13  # _moved: 1.0 / 0.0
    sq_speed_error = 14
    driven_time = 15
    speed_min = 16  # speed_min_creeping
    t_last = 17
    resting = 18  # _rest is not None: 1.0 / 0.0
    rest_row = 19  # out: the row whose sample starts the rest (-1: none in these rows)
    v_prev = 20  # _v_prev: the last sample's speed (NaN: none yet), for the roll-back's trapezoid


class Run(IntEnum):
    """The open run ``run``: its driving clutch (0 none, 1 CL, 2 CH; -1 before the first row), end and first
    instant, which of :class:`Slot` are filled (1.0 / 0.0), and the window ring's head and length."""

    code = 0
    end = 1
    first_t = 2
    has_first = 3
    has_settled = 4
    has_lagged = 5
    has_last = 6
    ring_head = 7
    ring_count = 8


class Slot(IntEnum):
    """Rows of the open run, as the samples of :class:`dsg_hil.results.summary._Run`."""

    first = 0
    settled = 1
    lagged = 2
    last = 3
    tail = 4


COLUMNS, ACC, RUN, SLOTS = (tuple(e.__members__) for e in (Col, Acc, Run, Slot))
_LIMIT = SAFETY_TEMPERATURE_C


@compiled
def creep_rows(rows, start, cols, dt, creep_request, desired_speed, acc, run, slots, ring, ring_t):
    """Accumulate ``rows[start:]`` into ``acc`` (:class:`Acc`) and the open run (:class:`Run`, :class:`Slot`, the
    window ``ring``/``ring_t``) as ``CreepMetrics.add`` does row by row with ``creep_request`` (1.0 / 0.0) and
    ``desired_speed`` held. Returns the row at which the driving clutch changes (its run to be closed and a new
    one opened, ``run[Run.code]`` is already its code, before calling again from it), or the number of rows;
    ``acc[Acc.rest_row]`` is set to the row whose sample starts a rest."""
    c_t, c_v, c_in, c_ocl, c_och = cols[Col.t], cols[Col.v], cols[Col.omega_in], cols[Col.omega_CL], cols[Col.omega_CH]
    c_pcl, c_pch, c_tcl, c_tch = cols[Col.P_CL], cols[Col.P_CH], cols[Col.T_CL], cols[Col.T_CH]
    c_mcl, c_mch, c_qcl, c_qch = cols[Col.M_CL], cols[Col.M_CH], cols[Col.Q_CL], cols[Col.Q_CH]
    cap = ring.shape[0]
    n = rows.shape[0]
    tail, last = -1, -1
    stop = n
    for k in range(start, n):
        r = rows[k]
        omega_in, M_CL, M_CH, P_CL, P_CH = r[c_in], r[c_mcl], r[c_mch], r[c_pcl], r[c_pch]
        cl = (abs(M_CL) > TORQUE_MIN if M_CL == M_CL else P_CL > P_ENGAGED) and abs(omega_in - r[c_ocl]) > SLIP_MIN
        ch = (abs(M_CH) > TORQUE_MIN if M_CH == M_CH else P_CH > P_ENGAGED) and abs(omega_in - r[c_och]) > SLIP_MIN
        both = cl and ch
        if both:
            if M_CL == M_CL and M_CH == M_CH:
                a, b = abs(M_CL), abs(M_CH)
            else:
                a, b = P_CL, P_CH
            clutch = 1 if a >= b else 2
        else:
            clutch = 1 if cl else 2 if ch else 0
        if clutch != run[Run.code]:
            run[Run.code] = clutch
            stop = k
            break
        t = r[c_t]
        if clutch != 0:
            acc[Acc.slip_CL + clutch - 1] += dt
            acc[Acc.overlap] += dt if both else 0.0
        run[Run.end] = t + dt
        tail = k
        if clutch != 0 and not both:
            if run[Run.has_first] == 0.0:
                slots[Slot.first, :] = r
                run[Run.first_t], run[Run.has_first] = t, 1.0
            if run[Run.has_settled] == 0.0 and t >= run[Run.first_t] + SETTLE_S - 1e-9:
                slots[Slot.settled, :] = r
                run[Run.has_settled] = 1.0
            head, count = int(run[Run.ring_head]), int(run[Run.ring_count])
            if count == cap:
                raise ValueError("creep_rows: the window ring is full")
            j = (head + count) % cap
            ring[j, :] = r
            ring_t[j] = t
            count += 1
            while ring_t[head] <= t - SETTLE_S + 1e-9:
                slots[Slot.lagged, :] = ring[head]
                run[Run.has_lagged] = 1.0
                head = (head + 1) % cap
                count -= 1
            run[Run.ring_head], run[Run.ring_count] = head, count
            last = k
        for i in range(2):  # CL, CH: their accumulators are next to each other
            T = r[c_tcl] if i == 0 else r[c_tch]
            Q = r[c_qcl] if i == 0 else r[c_qch]
            if T == T:
                peak = acc[Acc.max_T_CL + i]
                if peak != peak or T > peak:
                    acc[Acc.max_T_CL + i] = T
                if T > _LIMIT:
                    acc[Acc.above_CL + i] += dt
            if Q == Q:
                acc[Acc.energy_CL + i] += Q * dt
        v = r[c_v]
        if v < 0.0:
            acc[Acc.rollback_speed] = min(acc[Acc.rollback_speed], v)
        prev = acc[Acc.v_prev]
        moved = 0.5 * (v + (v if prev != prev else prev))  # mean speed since the last sample (trapezoid)
        acc[Acc.v_prev] = v
        if moved < 0.0:
            acc[Acc.rollback_distance] -= moved * dt
        if creep_request == 0.0:
            continue
        if v > V_MOVING:
            acc[Acc.creep] += dt
            acc[Acc.resting] = 0.0
            acc[Acc.rest_row] = -1.0
            if acc[Acc.moved] == 0.0 and v >= ESTABLISHED * desired_speed:
                acc[Acc.moved] = 1.0
        else:
            if abs(v) <= V_MOVING:
                acc[Acc.standstill] += dt
            if acc[Acc.moved] != 0.0 and acc[Acc.resting] == 0.0:
                acc[Acc.resting] = 1.0
                acc[Acc.rest_row] = k
        if acc[Acc.moved] != 0.0 and clutch != 0:
            acc[Acc.sq_speed_error] += (v - desired_speed) ** 2 * dt
            acc[Acc.driven_time] += dt
            speed_min = acc[Acc.speed_min]
            acc[Acc.speed_min] = v if speed_min != speed_min else min(speed_min, v)
        acc[Acc.t_last] = t + dt
    if tail >= 0:
        slots[Slot.tail, :] = rows[tail]
    if last >= 0:
        slots[Slot.last, :] = rows[last]
        run[Run.has_last] = 1.0
    return stop


def columns(fields: tuple[str, ...]) -> np.ndarray:
    """``cols`` of :func:`creep_rows` for rows whose columns are named by ``fields``."""
    return np.array([fields.index(name) for name in COLUMNS], dtype=np.int64)


_KERNEL: list = []


def kernel():  # noqa: ANN201 - numba's compiled function
    """:func:`creep_rows` compiled for its argument types once, called without numba's per-call typing."""
    if not _KERNEL:
        rows, z = np.zeros((1, len(COLUMNS))), np.zeros(1)
        _KERNEL.append(creep_rows.specialize(rows, 0, columns(COLUMNS), 0.0, 0.0, 0.0, np.zeros(len(Acc)),
                                             np.zeros(len(Run)), np.zeros((len(Slot), 1)), rows, z))
    return _KERNEL[0]
