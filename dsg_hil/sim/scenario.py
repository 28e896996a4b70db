"""Scenarios: the driver's inputs over time, road grade, initial temperatures and speed, duration (TOML).

```toml
name = "creep on grade"
duration_s = 200.0
grade_rad = 0.174            # optional; default: the parameter file's vehicle.beta
engine_speed_rpm = 800.0     # optional; idle governor setpoint
[initial]
T_clutch_c = 100.0           # plates of CL and CH
T_CL_c = 100.0               # optional: CL's plates (default T_clutch_c)
T_CH_c = 100.0               # optional: CH's plates (default T_clutch_c)
T_oil_c = 90.0               # every other node
v_mps = 0.0
[[driver]]                   # piecewise constant from t_s on
t_s = 0.0
creep_request = false
brake = 1.0                  # 0..1
desired_speed_mps = 0.0
[[fault]]                    # optional, any number: see dsg_hil.protocol.faults.spec
kind = "drop"
target = "TCU_CMD"
start_s = 10.0
end_s = 12.0
```
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..common.errors import InputError
from ..common.files import read_input_file
from ..protocol.faults import FaultError, FaultSpec, fault_from_mapping

__all__ = ["DEFAULT_SCENARIO", "DriverInput", "Scenario", "ScenarioError", "load_scenario", "parse_scenario"]

DEFAULT_SCENARIO = Path(__file__).resolve().parents[1] / "data" / "creep.toml"


class ScenarioError(InputError):
    """A scenario file is missing, unreadable or has a bad value (the message names the key)."""


@dataclass(frozen=True)
class DriverInput:
    t_s: float
    creep_request: bool
    brake: float
    desired_speed_mps: float


@dataclass(frozen=True)
class Scenario:
    name: str
    duration_s: float
    grade_rad: float | None
    engine_speed_rpm: float | None
    T_clutch_c: float
    T_oil_c: float
    T_CL_c: float
    T_CH_c: float
    v_mps: float
    driver: tuple[DriverInput, ...]
    faults: tuple[FaultSpec, ...] = ()  # checked against the DBC when the run starts

    def initial_temperatures(self, nodes: tuple[str, ...]) -> dict[str, float]:
        """Start temperature of each thermal node [degC]: the plates CL and CH their own, every other T_oil_c."""
        return {n: self.T_oil_c for n in nodes} | {"CL": self.T_CL_c, "CH": self.T_CH_c}

    def driver_at(self, t: float) -> DriverInput:
        """The driver's inputs in force at time t [s] (the last event at or before t; compared exactly: the
        plant's time is the float of a whole number of ns, as a decimal t_s of the scenario file is)."""
        current = self.driver[0]
        for event in self.driver:
            if event.t_s <= t:
                current = event
            else:
                break
        return current

    def with_duration(self, duration_s: float) -> Scenario:
        if not 1e-3 <= duration_s <= 1e6:  # as duration_s in a scenario file (and no NaN, no inf)
            raise ScenarioError(f"--duration: must be within [0.001, 1e6] s, got {duration_s}")
        return replace(self, duration_s=duration_s)


def _number(table: dict, key: str, where: str, lo: float, hi: float, default: Any = ...) -> Any:
    if key not in table:
        if default is ...:
            raise ScenarioError(f"{where}{key}: missing")
        return default
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ScenarioError(f"{where}{key}: must be a number, got {value!r}")
    if not lo <= value <= hi:
        raise ScenarioError(f"{where}{key}: {value} is out of range [{lo}, {hi}]")
    return float(value)


def parse_scenario(text: str, origin: str = "<string>") -> Scenario:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{origin}: not valid TOML: {exc}") from None
    known = {"name", "duration_s", "grade_rad", "engine_speed_rpm", "initial", "driver", "fault"}
    unknown = set(data) - known
    if unknown:
        raise ScenarioError(f"{origin}: {sorted(unknown)[0]}: unknown key")
    initial = data.get("initial", {})
    if not isinstance(initial, dict):
        raise ScenarioError("initial: must be a table")
    extra = set(initial) - {"T_clutch_c", "T_CL_c", "T_CH_c", "T_oil_c", "v_mps"}
    if extra:
        raise ScenarioError(f"initial.{sorted(extra)[0]}: unknown key")
    T_clutch = _number(initial, "T_clutch_c", "initial.", -40.0, 300.0, 25.0)
    events = data.get("driver")
    if not isinstance(events, list) or not events:
        raise ScenarioError("driver: needs at least one [[driver]] event")
    driver = []
    for i, ev in enumerate(events):
        where = f"driver[{i}]."
        if not isinstance(ev, dict):
            raise ScenarioError(f"driver[{i}]: must be a table ([[driver]]), got {ev!r}")
        extra = set(ev) - {"t_s", "creep_request", "brake", "desired_speed_mps"}
        if extra:
            raise ScenarioError(f"{where}{sorted(extra)[0]}: unknown key")
        creep = ev.get("creep_request", False)
        if not isinstance(creep, bool):
            raise ScenarioError(f"{where}creep_request: must be true or false")
        driver.append(DriverInput(_number(ev, "t_s", where, 0.0, 1e6), creep,
                                  _number(ev, "brake", where, 0.0, 1.0, 0.0),
                                  _number(ev, "desired_speed_mps", where, 0.0, 5.0, 0.0)))
    if any(b.t_s < a.t_s for a, b in zip(driver, driver[1:])):
        raise ScenarioError("driver: events must be in time order")
    tables = data.get("fault", [])
    if not isinstance(tables, list) or not all(isinstance(table, dict) for table in tables):
        raise ScenarioError("fault: must be [[fault]] tables")
    try:
        faults = tuple(fault_from_mapping(table, f"fault[{i}]") for i, table in enumerate(tables))
    except FaultError as exc:
        raise ScenarioError(str(exc)) from None
    name = data.get("name", Path(origin).stem)
    return Scenario(
        name=str(name),
        duration_s=_number(data, "duration_s", "", 1e-3, 1e6),
        grade_rad=_number(data, "grade_rad", "", -0.5, 0.5, None),
        engine_speed_rpm=_number(data, "engine_speed_rpm", "", 500.0, 2500.0, None),
        T_clutch_c=T_clutch,
        T_oil_c=_number(initial, "T_oil_c", "initial.", -40.0, 200.0, 25.0),  # (the range's 150 degC and beyond)
        T_CL_c=_number(initial, "T_CL_c", "initial.", -40.0, 300.0, T_clutch),
        T_CH_c=_number(initial, "T_CH_c", "initial.", -40.0, 300.0, T_clutch),
        v_mps=_number(initial, "v_mps", "initial.", -5.0, 5.0, 0.0),
        driver=tuple(driver),
        faults=faults,
    )


def load_scenario(path: str | Path | None = None) -> Scenario:
    path = Path(path) if path is not None else DEFAULT_SCENARIO
    text = read_input_file(path, "scenario", ScenarioError)
    return parse_scenario(text, str(path))
