"""The per-step part of :meth:`dsg_hil.results.summary.CreepMetrics.add`, compiled, over the rows of a plant trace.

:func:`creep_rows` runs the same operations as ``CreepMetrics.add`` on each row in turn (so its sums and extremes
are the same to the last bit) and keeps the open run of the driving clutch as rows (:data:`SLOTS`, and the window of the
samples at which its clutch slips alone, a ring of rows): Python makes samples of rows only when a run ends (the
kernel returns there) and when a rest starts.
"""

from __future__ import annotations

import numpy as np

from ..physics.jit import compiled
from .thresholds import ESTABLISHED, P_ENGAGED, SAFETY_TEMPERATURE_C, SETTLE_S, SLIP_MIN, TORQUE_MIN, V_MOVING

# Columns read (``cols`` holds their indices in the rows), the accumulators (``acc``; NaN: None) and the open
# run's state (``run``; its code 0 none, 1 CL, 2 CH; -1 before the first row).
COLUMNS = ("t", "v", "omega_in", "omega_CL", "omega_CH", "P_CL", "P_CH", "T_CL", "T_CH", "M_CL", "M_CH", "Q_CL",
           "Q_CH")
ACC = ("slip_CL", "slip_CH", "overlap", "max_T_CL", "max_T_CH", "above_CL", "above_CH", "energy_CL", "energy_CH",
       "rollback_speed", "rollback_distance", "creep", "standstill", "moved", "sq_speed_error", "driven_time",
       "speed_min", "t_last", "resting", "rest_row")
RUN = ("code", "end", "first_t", "has_first", "has_settled", "has_lagged", "has_last", "ring_head", "ring_count")
SLOTS = ("first", "settled", "lagged", "last", "tail")  # rows of the open run, as _Run's samples
_LIMIT = SAFETY_TEMPERATURE_C


@compiled
def creep_rows(rows, start, cols, dt, creep_request, desired_speed, acc, run, slots, ring, ring_t):
    """Accumulate ``rows[start:]`` into ``acc`` (:data:`ACC`) and the open run (:data:`RUN`, :data:`SLOTS`, the
    window ``ring``/``ring_t``) as ``CreepMetrics.add`` does row by row with ``creep_request`` (1.0 / 0.0) and
    ``desired_speed`` held. Returns the row at which the driving clutch changes (its run to be closed and a new
    one opened, ``run[0]`` is already its code, before calling again from it), or the number of rows; ``acc[rest_row]``
    is set to the row whose sample starts a rest."""
    c_t, c_v, c_in, c_ocl, c_och = cols[0], cols[1], cols[2], cols[3], cols[4]
    c_pcl, c_pch, c_tcl, c_tch, c_mcl, c_mch, c_qcl, c_qch = (cols[5], cols[6], cols[7], cols[8], cols[9],
                                                              cols[10], cols[11], cols[12])
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
        if clutch != run[0]:
            run[0] = clutch
            stop = k
            break
        t = r[c_t]
        if clutch != 0:
            acc[clutch - 1] += dt
            acc[2] += dt if both else 0.0
        run[1] = t + dt
        tail = k
        if clutch != 0 and not both:
            if run[3] == 0.0:
                slots[0, :] = r
                run[2], run[3] = t, 1.0
            if run[4] == 0.0 and t >= run[2] + SETTLE_S - 1e-9:
                slots[1, :] = r
                run[4] = 1.0
            head, count = int(run[7]), int(run[8])
            if count == cap:
                raise ValueError("creep_rows: the window ring is full")
            j = (head + count) % cap
            ring[j, :] = r
            ring_t[j] = t
            count += 1
            while ring_t[head] <= t - SETTLE_S + 1e-9:
                slots[2, :] = ring[head]
                run[5] = 1.0
                head = (head + 1) % cap
                count -= 1
            run[7], run[8] = head, count
            last = k
        for i in range(2):
            T = r[c_tcl] if i == 0 else r[c_tch]
            Q = r[c_qcl] if i == 0 else r[c_qch]
            if T == T:
                peak = acc[3 + i]
                if peak != peak or T > peak:
                    acc[3 + i] = T
                if T > _LIMIT:
                    acc[5 + i] += dt
            if Q == Q:
                acc[7 + i] += Q * dt
        v = r[c_v]
        if v < 0.0:
            acc[9] = min(acc[9], v)
            acc[10] -= v * dt
        if creep_request == 0.0:
            continue
        if v > V_MOVING:
            acc[11] += dt
            acc[18] = 0.0
            acc[19] = -1.0
            if acc[13] == 0.0 and v >= ESTABLISHED * desired_speed:
                acc[13] = 1.0
        else:
            if abs(v) <= V_MOVING:
                acc[12] += dt
            if acc[13] != 0.0 and acc[18] == 0.0:
                acc[18] = 1.0
                acc[19] = k
        if acc[13] != 0.0 and clutch != 0:
            acc[14] += (v - desired_speed) ** 2 * dt
            acc[15] += dt
            acc[16] = v if acc[16] != acc[16] else min(acc[16], v)
        acc[17] = t + dt
    if tail >= 0:
        slots[4, :] = rows[tail]
    if last >= 0:
        slots[3, :] = rows[last]
        run[6] = 1.0
    return stop


def columns(fields: tuple[str, ...]) -> np.ndarray:
    """``cols`` of :func:`creep_rows` for rows whose columns are named by ``fields``."""
    return np.array([fields.index(name) for name in COLUMNS], dtype=np.int64)


_KERNEL: list = []


def kernel():  # noqa: ANN201 - numba's compiled function
    """:func:`creep_rows` compiled for its argument types once, called without numba's per-call typing."""
    if not _KERNEL:
        rows, z = np.zeros((1, len(COLUMNS))), np.zeros(1)
        _KERNEL.append(creep_rows.specialize(rows, 0, columns(COLUMNS), 0.0, 0.0, 0.0, np.zeros(len(ACC)),
                                             np.zeros(len(RUN)), np.zeros((len(SLOTS), 1)), rows, z))
    return _KERNEL[0]
