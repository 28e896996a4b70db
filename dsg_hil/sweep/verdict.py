"""How a sweep judges a run, on the plant's truth: its summary flattened to one table row, and the violations.

A run's verdict (:func:`verdict`) is ``violation``, ``outside_range`` (none violated, but an input lies outside the
documented operating range, :mod:`dsg_hil.sim.operating_range`: the claim does not cover it) or ``ok``.

A run violates when (limits: :data:`LIMITS`, overridable in the space's ``[limits]``)

* ``plate``: a true plate temperature above ``plate_temp_c`` (the creep strategy's 250 degC, Section IV);
* ``rollback``: the vehicle rolled back more than ``rollback_m`` (summary ``rollback_m``);
* ``overspeed``: the true speed exceeded the highest desired creep speed by more than ``overspeed_mps``;
* ``fault``: the TCU spent more than ``fault_s`` in FAULT that no injected frame fault explains
  (:func:`fault_windows`: FAULT is the expected, safe reaction to a plant frame that is missing or invalid, so it
  is judged by the vehicle's roll-back and speed there; FAULT outside those windows is a false alarm that leaves
  the driver without creep);
* ``standstill``: the vehicle came to rest while creep was requested, the TCU had not stopped it for overheat
  (summary ``stop_reason`` ``vehicle_stopped``), the driver's pedal was at most ``standstill_brake`` from then
  until the summary calls it stopped (``brake_at_stop``; a pressed brake stops creep by design), and the stop did
  not begin in a fault window (``stop_in_fault_window``: holding the vehicle is the TCU's safe reaction to an
  injected fault, FAULT on missing plant frames or the hold on lost commands, judged there by roll-back and speed).

A run with latent sensor faults (a space's ``[latent]``, :mod:`.latent`) is judged as any other; its row's
``latent_x`` is the largest of their errors as a multiple of the signal's detection threshold, and
:func:`latent_class` sorts it (``beyond``: some fault beyond its threshold; ``within``: all within, which the TCU
cannot see; ``none``), so the verdict of a sweep says how many violating runs had which (:func:`latent_counts`).

The summary's failure metrics (``max_speed_creep_mps``, ``overspeed_mps``, ``rollback_guarded_m``,
``fault_time_s``) are read into row columns by :data:`OPTIONAL` (None where a summary lacks one, e.g. one read
back from an older sweep); the worker also measures the top speed itself from the truth (``v_max_mps``) and the
FAULT time outside the fault windows (``fault_unexplained_s``).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from typing import Any

from cantools.database import Database

from ..protocol.faults import FaultSpec
from ..protocol.validity import TIMEOUT_CYCLES
from ..results.thresholds import SAFETY_TEMPERATURE_C

__all__ = ["LATENT_CLASSES", "LIMITS", "OBJECTIVES", "OPTIONAL", "VIOLATIONS", "UnexplainedFault", "fault_windows",
           "in_windows", "latent_class", "latent_counts", "objective_value", "summary_row", "verdict", "violations"]

LIMITS: dict[str, float] = {"plate_temp_c": SAFETY_TEMPERATURE_C, "rollback_m": 0.05, "overspeed_mps": 0.5,
                            "fault_s": 0.0, "standstill_brake": 0.0}
VIOLATIONS = ("plate", "rollback", "overspeed", "fault", "standstill")
# the summary's failure metrics (results/outcome.py): row column <- summary key
OPTIONAL: dict[str, str] = {"max_speed_mps": "max_speed_creep_mps", "overspeed_mps": "overspeed_mps",
                            "rollback_creep_m": "rollback_guarded_m", "fault_time_s": "fault_time_s"}
# search objectives: name -> what is maximised (a row column; sign: +1 maximise it, -1 minimise it)
OBJECTIVES: dict[str, tuple[str, float]] = {"max_plate_temp_c": ("max_plate_temp_c", 1.0),
                                            "rollback_m": ("rollback_m", 1.0), "overspeed": ("v_max_mps", 1.0),
                                            "min_margin": ("margin_c", -1.0)}


def fault_windows(faults: Iterable[FaultSpec], db: Database) -> list[tuple[float, float]]:
    """The times at which the injected ``faults`` explain a TCU in FAULT: from each fault's start to its end plus
    what a receiver needs to see its message valid again after it: the frames' ``delay_s``, the receive deadline
    (:data:`~dsg_hil.protocol.validity.TIMEOUT_CYCLES` cycle times of the message, the DBC's longest for a fault
    that names none), one TCU control cycle (TCU_CMD's cycle time) to act on it, and one cycle of TCU_STATUS, through
    which the run sees the TCU's state."""
    def cycle_s(name: str) -> float:
        return (db.get_message_by_name(name).cycle_time or 0) / 1000.0

    longest, seen_acting_s = max(cycle_s(m.name) for m in db.messages), cycle_s("TCU_CMD") + cycle_s("TCU_STATUS")
    windows = []
    for spec in faults:
        cycle = longest if spec.message is None else cycle_s(spec.message)
        windows.append((spec.start_s, spec.end_s + spec.delay_s + TIMEOUT_CYCLES * cycle + seen_acting_s))
    return windows


def in_windows(t: float, windows: Iterable[tuple[float, float]]) -> bool:
    """Whether ``t`` lies in one of ``windows`` (closed intervals)."""
    return any(t0 <= t <= t1 for t0, t1 in windows)


class UnexplainedFault:
    """The time the TCU reports FAULT outside ``windows`` (:func:`fault_windows`), from its state once a period."""

    def __init__(self, windows: list[tuple[float, float]]) -> None:
        self.windows, self.seconds = windows, 0.0
        self._last: float | None = None

    def update(self, t: float, tcu_state: str) -> None:
        """The TCU's state ``tcu_state`` at time ``t``: the period since the last call counts if it is FAULT then
        and ``t`` lies outside every window."""
        if self._last is not None and tcu_state == "FAULT" and not in_windows(t, self.windows):
            self.seconds += t - self._last
        self._last = t


# the summary's keys whose value is a table or null (no first CH slip): the table's columns either way
SPLIT: dict[str, tuple[str, ...]] = {"mu_CH_first_slip": ("start", "end"), "P_CH_first_slip_mpa": ("start", "end")}


def _number(value: Any) -> float | None:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def summary_row(summary: Mapping[str, Any]) -> dict[str, Any]:
    """The summary JSON (``Summary.as_json()``) as flat columns: numbers and strings; a per-clutch table as
    ``key.CL``/``key.CH``; a list as its length (``n_handovers``, ``n_phases``)."""
    row: dict[str, Any] = {}
    for key, value in summary.items():
        if key == "outside_range":  # the offending inputs (dsg_hil.sim.operating_range), "" inside the range
            row[key] = "; ".join(value or ())
        elif key in ("command_fallback", "frames", "faults", "command_latency_ms"):
            row[key] = json.dumps(value, sort_keys=True, default=str)
        elif isinstance(value, Mapping):
            row.update({f"{key}.{k}": _number(v) if not isinstance(v, str) else v for k, v in value.items()
                        if not isinstance(v, (Mapping, list))})
        elif isinstance(value, list):
            row[f"n_{key}"] = len(value)
        elif value is None and key in SPLIT:  # the columns of a run that has the value, null (one schema)
            row.update({f"{key}.{part}": None for part in SPLIT[key]})
        elif isinstance(value, (int, float, str)) or value is None:
            row[key] = value
    row.setdefault("outside_range", "")  # (the summary has the key only where an input is outside)
    peaks = [v for v in (summary.get("max_plate_temp_c") or {}).values() if isinstance(v, (int, float))]
    row["max_plate_temp_c"] = max(peaks) if peaks else None
    for column, key in OPTIONAL.items():
        row[column] = _number(summary.get(key))
    return row


def violations(row: Mapping[str, Any], limits: Mapping[str, float]) -> list[str]:
    """The names (:data:`VIOLATIONS`) of what ``row`` violates."""
    found = []
    peak = row.get("max_plate_temp_c")
    if peak is not None and peak > limits["plate_temp_c"]:
        found.append("plate")
    if (row.get("rollback_m") or 0.0) > limits["rollback_m"]:
        found.append("rollback")
    speed = max(v for v in (row.get("v_max_mps"), row.get("max_speed_mps"), 0.0) if v is not None)
    if speed > (row.get("v_desired_max_mps") or 0.0) + limits["overspeed_mps"]:
        found.append("overspeed")
    unexplained = row.get("fault_unexplained_s", row.get("fault_time_s"))  # a row of an older sweep: all of it
    if (unexplained or 0.0) > limits["fault_s"]:
        found.append("fault")
    if (row.get("stop_reason") == "vehicle_stopped" and (row.get("brake_at_stop") or 0.0) <= limits["standstill_brake"]
            and not row.get("stop_in_fault_window")):
        found.append("standstill")
    return found


def verdict(row: Mapping[str, Any], found: list[str]) -> str:
    """A judged run's verdict: ``violation`` if it violates (``found``: :func:`violations`), else
    ``outside_range`` if an input lies outside the documented operating range (row column ``outside_range``:
    the offending inputs; no silent pass of a run the safety claim does not cover), else ``ok``."""
    if found:
        return "violation"
    return "outside_range" if row.get("outside_range") else "ok"


LATENT_CLASSES = {"beyond": "with a latent fault beyond its detection threshold",
                  "within": "with latent faults all within their thresholds", "none": "without a latent fault"}


def latent_class(row: Mapping[str, Any]) -> str:
    """A row's latent faults (column ``latent_x``, :data:`LATENT_CLASSES`): ``beyond`` if the largest is beyond its
    signal's detection threshold (> 1), ``within`` if it is not, ``none`` without any (or an older sweep's row)."""
    x = row.get("latent_x")
    if not isinstance(x, (int, float)) or x != x:  # None, or NaN read back from the table
        return "none"
    return "beyond" if x > 1.0 else "within"


def latent_counts(rows: Iterable[Mapping[str, Any]]) -> str:
    """How many of ``rows`` are in each :data:`LATENT_CLASSES` (those with any), e.g. ``5 with a latent fault
    beyond its detection threshold, 3 without a latent fault``; "" if none has a latent fault."""
    counts = {key: 0 for key in LATENT_CLASSES}
    for row in rows:
        counts[latent_class(row)] += 1
    if not counts["beyond"] and not counts["within"]:
        return ""
    return ", ".join(f"{n} {LATENT_CLASSES[key]}" for key, n in counts.items() if n)


def objective_value(row: Mapping[str, Any], objective: str) -> float:
    """What the search maximises for ``row`` (a failed run: -inf)."""
    column, sign = OBJECTIVES[objective]
    value = row.get(column)
    return sign * float(value) if isinstance(value, (int, float)) else float("-inf")
