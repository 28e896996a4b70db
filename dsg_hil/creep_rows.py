"""The per-step part of :meth:`dsg_hil.summary.CreepMetrics.add`, compiled, over the rows of a plant trace.

:func:`creep_rows` runs the same operations as ``CreepMetrics.add`` on each row in turn (so its sums and extremes
are the same to the last bit) and leaves to Python only what keeps samples: the runs of the driving clutch, from
the ``code`` (0 none, 1 CL, 2 CH) and ``alone`` (the clutch slips alone) it writes per row, and the rest's start.
"""

from __future__ import annotations

import numpy as np

from .physics.jit import compiled
from .reference import SAFETY_TEMPERATURE_C
from .summary import ESTABLISHED, P_ENGAGED, SLIP_MIN, TORQUE_MIN, V_MOVING

# Columns read (``cols`` holds their indices in the rows) and the accumulators (``acc``; NaN: None).
COLUMNS = ("t", "v", "omega_in", "omega_CL", "omega_CH", "P_CL", "P_CH", "T_CL", "T_CH", "M_CL", "M_CH", "Q_CL",
           "Q_CH")
ACC = ("slip_CL", "slip_CH", "overlap", "max_T_CL", "max_T_CH", "above_CL", "above_CH", "energy_CL", "energy_CH",
       "rollback_speed", "rollback_distance", "creep", "standstill", "moved", "sq_speed_error", "driven_time",
       "speed_min", "t_last", "resting", "rest_row")
_LIMIT = SAFETY_TEMPERATURE_C


@compiled
def creep_rows(rows, cols, dt, creep_request, desired_speed, acc, code, alone):
    """Accumulate ``rows`` into ``acc`` (:data:`ACC`) as ``CreepMetrics.add`` does row by row with
    ``creep_request`` (1.0 / 0.0) and ``desired_speed`` held; writes ``code`` and ``alone`` per row, and in
    ``acc[rest_row]`` the row whose sample starts the rest (-1: the rest did not start in these rows)."""
    c_t, c_v, c_in, c_ocl, c_och, c_pcl, c_pch, c_tcl, c_tch, c_mcl, c_mch, c_qcl, c_qch = (
        cols[0], cols[1], cols[2], cols[3], cols[4], cols[5], cols[6], cols[7], cols[8], cols[9], cols[10],
        cols[11], cols[12])
    acc[19] = -1.0
    for k in range(rows.shape[0]):
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
        code[k] = clutch
        alone[k] = clutch != 0 and not both
        if clutch != 0:
            acc[clutch - 1] += dt
            acc[2] += dt if both else 0.0
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
        acc[17] = r[c_t] + dt


def columns(fields: tuple[str, ...]) -> np.ndarray:
    """``cols`` of :func:`creep_rows` for rows whose columns are named by ``fields``."""
    return np.array([fields.index(name) for name in COLUMNS], dtype=np.int64)


_KERNEL: list = []


def kernel():  # noqa: ANN201 - numba's compiled function
    """:func:`creep_rows` compiled for its argument types once, called without numba's per-call typing."""
    if not _KERNEL:
        rows = np.zeros((1, len(COLUMNS)))
        _KERNEL.append(creep_rows.specialize(rows, columns(COLUMNS), 0.0, 0.0, 0.0, np.zeros(len(ACC)),
                                             np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.bool_)))
    return _KERNEL[0]
