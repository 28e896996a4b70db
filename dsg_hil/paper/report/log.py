"""A recorded bus log (candump -L, .asc, .blf, ... through python-can's LogReader) decoded with the DBC into the
time series of a creep run, sampled on the control period's grid, and its creep numbers
(:class:`dsg_hil.results.summary.CreepMetrics`: the same definitions as ``dsg-hil run --summary``).

Nothing here needs TCU_STATUS: a third-party ECU may not send it (then the predicted temperatures are NaN and
the TCU's handovers are absent). The simulation-only truth frames (SIM_*) are used when present; they come every
100 ms against the 10-ms grid, so their values are interpolated linearly between frames (held after the last),
not held from the last frame: held, a clutch's torque would show up to 100 ms late, and the phases, and the mu
and P taken 0.5 s into each, would differ from the per-step summary's during a launch.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
from cantools.database.can import Database

from ...protocol.logs import decoded_frames, log_codec
from ...common.errors import LogError
from ...results.summary import CreepMetrics
from ...sim.plant_io import SHIPPED, PlantIO

__all__ = ["GRID_MESSAGE", "SIGNALS", "STATUS", "TRUTH", "CreepRecord", "LogError", "LogSample", "read_log"]

NAN = float("nan")


class LogSample(NamedTuple):
    """The decoded bus at one instant, SI units, with the attribute names of :class:`dsg_hil.physics.plant.PlantOutputs`
    (NaN: not on the bus yet, or not at all)."""

    t: float
    v: float
    omega_in: float
    omega_CL: float
    omega_CH: float
    P_CL: float
    P_CH: float
    P_CL_cmd: float
    P_CH_cmd: float
    T_CL: float
    T_CH: float
    mu_CL: float
    mu_CH: float
    M_CL: float
    M_CH: float
    Q_CL: float
    Q_CH: float
    Q_diss_CL: float
    Q_diss_CH: float
    T_CL_pred: float
    T_CH_pred: float
    creep_request: float
    desired_speed_mps: float


INDEX = {name: i for i, name in enumerate(LogSample._fields)}
# (message, signal) -> (index in LogSample, factor to SI): the plant's table (dsg_hil.sim.plant_io.SIGNALS) for the
# signals whose quantity is a LogSample field
_TRUTH = frozenset(("T_CL", "T_CH", "mu_CL", "mu_CH", "M_CL", "M_CH", "Q_CL", "Q_CH", "Q_diss_CL", "Q_diss_CH"))


def _signals(io: PlantIO) -> dict[tuple[str, str], tuple[int, float]]:
    return {key: (INDEX[name], factor) for key, (name, factor) in io.signals.items() if name in INDEX}


SIGNALS = _signals(SHIPPED)  # of the shipped binding
STATUS = SHIPPED.status
TRUTH = frozenset(INDEX[name] for name in _TRUTH)  # the simulation's truth (SIM_* frames): interpolated
GRID_MESSAGE = SHIPPED.command  # the sampling period: the control period of the DBC


@dataclass(frozen=True)
class CreepRecord:
    """A decoded creep run: columns over the sample grid, its creep numbers and what was decoded."""

    source: str
    columns: dict[str, np.ndarray]  # LogSample fields, SI
    metrics: dict
    frames: dict[str, int]  # decoded, rejected (CRC, range, ...), unknown (IDs not in the DBC)
    has_status: bool

    def column(self, name: str) -> np.ndarray:
        return self.columns[name]


def read_log(path: str | Path, db: Database, io: PlantIO | None = None,
             protection: Mapping[str, Mapping[str, object]] | None = None) -> CreepRecord:
    """Decode the log at ``path`` with ``db`` and compute its creep numbers (one pass, in time order); ``io``: the
    plant's messages and signals on ``db`` (its binding's; None: the shipped DBC's); ``protection``: its binding's
    protection by message (the messages under an AUTOSAR profile or none)."""
    path = Path(path)
    io = io if io is not None else SHIPPED
    signals, offsets = (SIGNALS, {}) if io is SHIPPED else (_signals(io), io.offsets)
    codec = log_codec(db, protection)
    period = codec.cycle_time(io.command)
    row = [NAN] * len(LogSample._fields)
    events: list[tuple[float, dict | None, list[float]]] = []  # (t, TCU_STATUS values or None: a grid sample, row)
    truth: dict[int, tuple[list[float], list[float]]] = {i: ([], []) for i in TRUTH}  # frame times, values
    counts: dict[str, int] = {}
    t0 = None
    k = 0  # grid instant t0 + k * period

    for timestamp, frame in decoded_frames(path, codec, counts):
        if t0 is None:
            t0 = timestamp
        while timestamp - t0 > k * period + 1e-6:  # the frames of grid instant k are all in
            events.append((k * period, None, row.copy()))
            k += 1
        if frame is None:
            continue
        for signal, value in frame.values.items():
            if (frame.name, signal) in signals:
                index, factor = signals[frame.name, signal]
                row[index] = value * factor + offsets.get((frame.name, signal), 0.0) if offsets else value * factor
                if index in truth:
                    truth[index][0].append(timestamp - t0)
                    truth[index][1].append(row[index])
        if frame.name == io.status:
            events.append((timestamp - t0, io.status_values(frame.values), row.copy()))
    if counts["decoded"] == 0:
        raise LogError(f"{path}: no frame of the DBC in the log ({counts['rejected']} rejected, "
                       f"{counts['unknown']} with unknown IDs)")
    events.append((k * period, None, row.copy()))
    _interpolate_truth(events, truth)
    metrics = CreepMetrics()
    samples: list[LogSample] = []
    for t, status, values in events:
        if status is None:
            values[0] = t
            s = LogSample(*values)
            samples.append(s)
            metrics.add(s, period, s.creep_request >= 0.5,
                        0.0 if math.isnan(s.desired_speed_mps) else s.desired_speed_mps)
        else:
            metrics.status(t, status["State"], status["ActiveClutch"], status["T_CL_Pred"], status["T_CH_Pred"],
                           LogSample(*values))
    columns = {name: np.array([s[i] for s in samples]) for i, name in enumerate(LogSample._fields)}
    return CreepRecord(str(path), columns, metrics.as_json(), counts, metrics.tcu_state is not None)


def _interpolate_truth(events: list[tuple[float, dict | None, list[float]]],
                       truth: dict[int, tuple[list[float], list[float]]]) -> None:
    """Each event's SIM_* values linearly between the frames around it (from the first frame on; held after the
    last), in place."""
    times = np.array([t for t, _, _ in events])
    for index, (frame_t, frame_v) in truth.items():
        if not frame_t:
            continue
        values = np.interp(times, frame_t, frame_v)
        for (t, _, event_row), value in zip(events, values):
            if t >= frame_t[0]:
                event_row[index] = float(value)
