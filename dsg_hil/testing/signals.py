"""The bus traffic of a run as time series: every DBC signal of every frame, decoded with cantools."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable

import can
import numpy as np
from cantools.database.can import Database

__all__ = ["Signals", "decode_frames"]


class Signals(dict[str, np.ndarray]):
    """Decoded frames as numpy arrays: ``s["PLANT_VEHICLE.VehicleSpeed"]`` holds the signal's value in every frame
    of its message, in DBC units (choices as their numbers), ``s["PLANT_VEHICLE.t"]`` the frames' times [s]
    (simulated time: lockstep). Messages have their own cycle times, hence their own time axes;
    :meth:`at` samples any signal on another axis."""

    def time(self, key: str) -> np.ndarray:
        """The time axis of ``key`` ("MESSAGE.Signal")."""
        return self[f"{key.split('.')[0]}.t"]

    def at(self, key: str, t: np.ndarray | float) -> np.ndarray:
        """``key`` held from frame to frame, at the times ``t``: the value of the last frame sent at or before
        each time (NaN before the first)."""
        times, values = self.time(key), self[key].astype(float)
        i = np.searchsorted(times, np.asarray(t, dtype=float), side="right") - 1
        return np.where(i >= 0, values[np.clip(i, 0, None)], np.nan) if len(values) else np.full(np.shape(t), np.nan)


def decode_frames(db: Database, frames: Iterable[can.Message]) -> Signals:
    """Every frame of a DBC message decoded (Counter and CRC included); frames of other IDs are left out."""
    columns: defaultdict[str, list[float]] = defaultdict(list)
    names: set[str] = set()
    for msg in frames:
        try:
            message = db.get_message_by_frame_id(msg.arbitration_id)
        except KeyError:
            continue
        names.add(message.name)
        columns[f"{message.name}.t"].append(msg.timestamp)
        decoded = message.decode(bytes(msg.data), decode_choices=False)
        assert isinstance(decoded, dict)  # (a container message would give a list; this DBC has none)
        for name, value in decoded.items():
            columns[f"{message.name}.{name}"].append(float(value))  # type: ignore[arg-type]
    signals = Signals({key: np.asarray(values) for key, values in columns.items()})
    for message in db.messages:  # a message never sent: empty arrays, so a test fails on values, not on a key
        if message.name not in names:
            signals[f"{message.name}.t"] = np.empty(0)
            signals.update({f"{message.name}.{s.name}": np.empty(0) for s in message.signals})
    return signals
