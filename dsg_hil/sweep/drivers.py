"""Driver-behaviour generators: a sample's ``driver.*`` settings made into the scenario's ``[[driver]]`` events
(piecewise constant, :class:`dsg_hil.sim.scenario.DriverInput`).

Every behaviour starts with the brake held (``brake_s``, default 1 s), then:

* ``creep``: creep at ``desired_speed_mps`` to the end;
* ``stop_and_go``: creep ``creep_s``, brake (creep released) ``stop_s``, again, to the end;
* ``brake_drag``: creep, with the light brake drag below applied (it applies to any behaviour whose
  ``drag_level`` > 0): the pedal at ``drag_level`` (0..1) from ``drag_onset_s`` for ``drag_duration_s`` while
  creep stays requested;
* ``speed_changes``: the desired speed alternates ``desired_speed_mps`` / ``speed_2_mps`` every ``change_s``;
* ``creep_toggles``: the creep request on ``toggle_s``, off ``toggle_s`` (the brake pressed while off if
  ``toggle_brake``), again;
* ``overheat_restart``: creep until ``stop_at_s`` (hot clutches: the TCU has stopped by then), creep released and
  the brake held ``pause_s``, then creep again: the restart from hot plates.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

from ..common.errors import InputError

__all__ = ["BEHAVIOURS", "DEFAULTS", "SETTINGS", "DriverError", "driver_events", "scenario_tables", "scenario_toml"]

BEHAVIOURS = ("creep", "stop_and_go", "brake_drag", "speed_changes", "creep_toggles", "overheat_restart")
DEFAULTS: dict[str, Any] = {
    "behaviour": "creep", "desired_speed_mps": 0.206, "brake_s": 1.0, "creep_s": 20.0, "stop_s": 5.0,
    "drag_level": 0.0, "drag_onset_s": 0.0, "drag_duration_s": 0.0, "speed_2_mps": 0.1, "change_s": 10.0,
    "toggle_s": 10.0, "toggle_brake": True, "stop_at_s": 150.0, "pause_s": 10.0}
SETTINGS = tuple(DEFAULTS)
MIN_PERIOD_S = 0.1  # a repeating behaviour's shortest phase (bounds the number of events)

Event = tuple[float, bool, float, float]  # t_s, creep_request, brake, desired_speed_mps


class DriverError(InputError):
    """A driver setting that makes no behaviour (a period too short, a level out of 0..1)."""


def _repeat(start: float, end: float, phases: list[tuple[float, bool, float, float]]) -> list[Event]:
    """``phases`` ((length, creep, brake, speed) ...) over and over from ``start`` to ``end``."""
    events: list[Event] = []
    t, i = start, 0
    while t < end:
        length, creep, brake, speed = phases[i % len(phases)]
        events.append((t, creep, brake, speed))
        t, i = t + length, i + 1
    return events


def _setting(s: Mapping[str, Any], key: str, lo: float = 0.0, hi: float = 1e6) -> float:
    value = s[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
        raise DriverError(f"inputs.driver.{key}: must be a number in [{lo:g}, {hi:g}], got {value!r}")
    return float(value)


def driver_events(settings: Mapping[str, Any], duration_s: float) -> list[dict[str, Any]]:
    """The ``[[driver]]`` tables of a behaviour (:data:`DEFAULTS` for the settings not given)."""
    s = {**DEFAULTS, **settings}
    behaviour = s["behaviour"]
    if behaviour not in BEHAVIOURS:
        raise DriverError(f"inputs.driver.behaviour: {behaviour!r} is not one of {', '.join(BEHAVIOURS)}")
    v, t0 = _setting(s, "desired_speed_mps", 0.0, 5.0), _setting(s, "brake_s")
    creep, brake = (True, 0.0, v), (False, 1.0, 0.0)
    events: list[Event] = [(0.0, *brake)]
    if behaviour in ("creep", "brake_drag"):
        events.append((t0, *creep))
    elif behaviour == "stop_and_go":
        events += _repeat(t0, duration_s, [(_setting(s, "creep_s", MIN_PERIOD_S), *creep),
                                           (_setting(s, "stop_s", MIN_PERIOD_S), *brake)])
    elif behaviour == "speed_changes":
        every = _setting(s, "change_s", MIN_PERIOD_S)
        events += _repeat(t0, duration_s, [(every, *creep), (every, True, 0.0, _setting(s, "speed_2_mps", 0.0, 5.0))])
    elif behaviour == "creep_toggles":
        off = (False, 1.0 if s["toggle_brake"] else 0.0, 0.0)
        every = _setting(s, "toggle_s", MIN_PERIOD_S)
        events += _repeat(t0, duration_s, [(every, *creep), (every, *off)])
    else:  # overheat_restart
        stop = max(_setting(s, "stop_at_s"), t0)
        events += [(t0, *creep), (stop, *brake), (stop + _setting(s, "pause_s"), *creep)]
    level = _setting(s, "drag_level", 0.0, 1.0)
    if level > 0.0:
        onset = _setting(s, "drag_onset_s")
        events = _with_drag(events, level, onset, onset + _setting(s, "drag_duration_s"))
    return [{"t_s": round(t, 3), "creep_request": c, "brake": round(b, 4), "desired_speed_mps": round(sp, 4)}
            for t, c, b, sp in _merged(events)]


def _with_drag(events: list[Event], level: float, start: float, end: float) -> list[Event]:
    """``events`` with the brake at least ``level`` in [start, end)."""
    times = sorted({t for t, *_ in events} | {start, end})
    out: list[Event] = []
    for t in times:
        current = [e for e in events if e[0] <= t][-1]
        brake = max(current[2], level) if start <= t < end else current[2]
        out.append((t, current[1], brake, current[3]))
    return out


def _merged(events: list[Event]) -> list[Event]:
    """Events in time order, a later one at the same time replacing the earlier, repeats of the same state
    dropped."""
    by_time: dict[float, Event] = {}
    for event in events:
        by_time[round(event[0], 3)] = event
    out: list[Event] = []
    for t in sorted(by_time):
        event = by_time[t]
        if not out or out[-1][1:] != event[1:]:
            out.append(event)
    return out


def scenario_tables(base: Mapping[str, Any], values: Mapping[str, Any]) -> dict[str, Any]:
    """The scenario's TOML tables: ``base`` with the scenario fields of ``values`` and, if any ``driver.*`` is
    given, the behaviour's ``[[driver]]`` events in place of the base's."""
    tables = copy.deepcopy(dict(base))
    for key, value in values.items():
        if key.startswith("initial."):
            tables.setdefault("initial", {})[key.removeprefix("initial.")] = value
        elif key in ("grade_rad", "engine_speed_rpm", "duration_s"):
            tables[key] = value
    settings = {k.removeprefix("driver."): v for k, v in values.items() if k.startswith("driver.")}
    if settings:
        duration = tables.get("duration_s", 0.0)
        tables["driver"] = driver_events(settings, float(duration) if isinstance(duration, (int, float)) else 0.0)
    return tables


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    raise DriverError(f"cannot write {value!r} to a scenario")


def scenario_toml(tables: Mapping[str, Any]) -> str:
    """A scenario's TOML text (what ``dsg-hil run --scenario`` reads) from its tables."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in tables.items() if not isinstance(v, (dict, list))]
    for name, value in tables.items():
        if isinstance(value, dict):
            lines += ["", f"[{name}]", *(f"{k} = {_toml_value(v)}" for k, v in value.items())]
        elif isinstance(value, list):
            for row in value:
                lines += ["", f"[[{name}]]", *(f"{k} = {_toml_value(v)}" for k, v in row.items())]
    return "\n".join(lines) + "\n"
