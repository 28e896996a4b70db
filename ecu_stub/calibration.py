"""The TCU's calibration: what a transmission ECU is flashed with. Its own numbers, not the plant's.

One TOML file (default: ``ecu_stub/data/calibration.toml``; ``ecu-stub --calibration FILE``). Every value is an
inline table ``{ value = ..., unit = "...", source = "...", how = "..." }`` where ``source`` is

* ``identified``: fitted to a recorded run by ``python -m ecu_stub.identify`` (``how`` names the run and command),
* ``derived``: computed from other values (``how`` gives the derivation),
* ``chosen``: an engineering choice or a vehicle data-sheet value (``how`` gives the reason).

Anything missing, unknown, mistyped, out of range or in another unit raises :class:`CalibrationError` naming
the key. Units are SI with temperatures in degC and pressures in MPa (the DBC's units for the TCU's commands).
"""

from __future__ import annotations

import functools
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from dsg_hil.common.errors import InputError
from dsg_hil.common.files import read_input_file
from dsg_hil.common.quantities import finite, quantity

__all__ = ["CalibrationError", "Clutch", "DEFAULT_CALIBRATION", "FrictionMap", "Launch", "SECTIONS", "SOURCES",
           "SpeedControl", "Strategy", "TcuCalibration", "Vehicle", "c", "dump_calibration", "load_calibration",
           "parse_calibration", "raw_sections", "torque_falls"]

DEFAULT_CALIBRATION = Path(__file__).resolve().parent / "data" / "calibration.toml"
SOURCES = ("identified", "derived", "chosen")


class CalibrationError(InputError):
    """A calibration file is missing, unreadable, or has a bad, missing or unknown value (the message names it)."""


def c(unit: str, lo: float | None = None, hi: float | None = None) -> Any:
    """A calibration field with its unit and allowed range [lo, hi]."""
    return field(metadata={"unit": unit, "lo": lo, "hi": hi})


@dataclass(frozen=True)
class Strategy:
    """Section V.A's safety temperature and how close to it the TCU lets a plate come (see the TOML's derivation)."""

    T_safe_c: float = c("degC", 100.0, 400.0)  # clutch safety temperature (paper, Section V.A)
    prediction_error_k: float = c("K", 0.0, 30.0)  # worst truth-minus-prediction over the identification runs
    oil_accuracy_k: float = c("K", 0.0, 30.0)  # an oil sensor's error no check can see (present from start-up)
    takeover_headroom_k: float = c("K", 0.0, 50.0)  # the on-coming clutch needs this much below its threshold
    handover_time_s: float = c("s", 0.05, 5.0)  # torque crossover duration
    hydraulic_lag_s: float = c("s", 0.0, 1.0)  # pressure follows the command with this lag (for the margin)
    dwell_band_k: float = c("K", 0.0, 20.0)  # a plate kept this close below its threshold ...
    dwell_time_s: float = c("s", 1.0, 600.0)  # ... for this long is treated as having reached it
    startup_observer_s: float = c("s", 0.0, 60.0)  # start-up: no creep while the plate estimate comes from the oil
    stop_release_s: float = c("s", 0.0, 2.0)  # STOPPED_OVERHEAT: clutch torque ramps out while the brake comes in


@dataclass(frozen=True)
class SpeedControl:
    """PI on vehicle speed with a wheel-force output, split over the clutches by the torque handover."""

    kp_n_per_mps: float = c("N/(m/s)", 0.0, 1e7)
    ki_n_per_m: float = c("N/m", 0.0, 1e8)
    force_rate_n_per_s: float = c("N/s", 1.0, 1e8)
    P_max_mpa: float = c("MPa", 0.1, 1.5)
    overspeed_fraction: float = c("1", 0.0, 1.0)  # over target by this, the brakes at their limit: the full brake
    decel_max_mps2: float = c("m/s^2", 0.0, 12.0)  # the most deceleration the speed control asks of the brakes


@dataclass(frozen=True)
class Launch:
    """Hill-hold and pre-fill: the vehicle is held by a brake request until the clutch carries F_prefill."""

    F_prefill_n: float = c("N", 0.0, 1e6)
    prefill_ready_fraction: float = c("1", 0.1, 1.0)  # measured pressure / pre-fill pressure to release the brake
    standstill_mps: float = c("m/s", 0.0, 0.5)
    accel_mps2: float = c("m/s^2", 0.01, 5.0)  # the speed reference rises to the desired creep speed at this rate
    grade_max_rad: float = c("rad", 0.0, 0.8)  # the steepest grade the accelerometer's reading is taken as
    push_fraction: float = c("1", 0.0, 1.0)  # a first launch's pre-fill: at most this of the lightest's road load


@dataclass(frozen=True)
class Vehicle:
    """Vehicle data-sheet values the TCU is flashed with (gains, the pre-fill, the plausibility checks)."""

    m_kg: float = c("kg", 100.0, 1e5)
    m_max_kg: float = c("kg", 100.0, 1e5)  # the heaviest the vehicle may be (laden): a first launch's pre-fill
    m_min_kg: float = c("kg", 100.0, 1e5)  # the lightest (empty): a first launch's pre-fill must not push it off
    f_roll: float = c("1", 0.0, 1.0)  # rolling resistance coefficient while moving (13)
    delta: float = c("1", 1.0, 3.0)  # rotating-mass factor
    eta: float = c("1", 0.5, 1.0)  # clutch-to-wheel torque efficiency
    input_ratio: float = c("1", 0.1, 20.0)  # engine speed / clutch input speed (i_a): the input speed check
    brake_decel_mps2: float = c("m/s^2", 0.0, 1000.0)  # full pedal's deceleration of the lightest vehicle: the vote


@dataclass(frozen=True)
class Clutch:
    """The TCU's model of one clutch: torque = mu * k_geom * P (5); C dT/dt = Q - K (T - T_oil_out)."""

    k_geom_m3: float = c("m^3", 1e-5, 1.0)  # N * A_f * r_m
    C_plate_j_k: float = c("J/K", 1.0, 1e6)
    K_plate_oil_w_k: float = c("W/K", 0.1, 1e5)
    speed_ratio_m: float = c("m", 1e-4, 1.0)  # vehicle speed per clutch output speed [m/s per rad/s]
    cooling_w_k: float = c("W/K", 0.0, 1e5)  # heat capacity flow of the cooling oil through the clutch (rho c_p q)


@dataclass(frozen=True)
class FrictionMap:
    """mu(T, slip, P): a map over plate temperature, slip speed and pressure, trilinear and clamped at its edges;
    formula (6)'s dependences, identified from recorded runs instead of its garbled printed constants."""

    T_grid_c: tuple[float, ...] = c("degC")
    slip_grid_rpm: tuple[float, ...] = c("rpm")
    P_grid_mpa: tuple[float, ...] = c("MPa")
    mu: tuple[tuple[tuple[float, ...], ...], ...] = c("1", 0.0, 0.5)  # [T index][slip index][P index]


@dataclass(frozen=True)
class TcuCalibration:
    strategy: Strategy
    speed: SpeedControl
    launch: Launch
    vehicle: Vehicle
    friction: FrictionMap
    CL: Clutch
    CH: Clutch

    def clutch(self, name: str) -> Clutch:
        return self.CL if name == "CL" else self.CH


SECTIONS = {"strategy": Strategy, "speed": SpeedControl, "launch": Launch, "vehicle": Vehicle,
            "friction": FrictionMap, "clutch.CL": Clutch, "clutch.CH": Clutch}


def _value(key: str, entry: Any, meta: Mapping[str, Any]) -> Any:
    value, _, _ = quantity(key, entry, meta["unit"], dict.fromkeys(SOURCES, "how"), CalibrationError)
    return _nested(key, value, meta["lo"], meta["hi"])


def _nested(key: str, value: Any, lo: float | None, hi: float | None) -> Any:
    """A number, or (nested) lists of numbers as tuples, each checked."""
    if isinstance(value, list):
        if not value:
            raise CalibrationError(f"{key}: empty list")
        return tuple(_nested(f"{key}[{i}]", x, lo, hi) for i, x in enumerate(value))
    return finite(key, value, CalibrationError, lo, hi)


def _section(data: dict, name: str, cls: type) -> Any:
    table: Any = data
    for part in name.split("."):
        if not isinstance(table, dict) or part not in table:
            raise CalibrationError(f"{name}: missing section")
        table = table[part]
    known = {f.name for f in fields(cls)}
    unknown = set(table) - known
    if unknown:
        raise CalibrationError(f"{name}.{sorted(unknown)[0]}: unknown key")
    values = {}
    for f in fields(cls):
        if f.name not in table:
            raise CalibrationError(f"{name}.{f.name}: missing")
        values[f.name] = _value(f"{name}.{f.name}", table[f.name], f.metadata)
    return cls(**values)


def torque_falls(m: FrictionMap) -> tuple[float, float, float, float] | None:
    """The first node (T [degC], slip [r/min]) and pressure span (P_lo, P_hi [MPa]) where the map's torque (5),
    M = mu(P) k_geom P, falls as the pressure rises, or None: where M rises with P the pressure for a torque is one
    (``clutch_model.pressure_for_torque``). In a span mu = a + b P is linear, so dM/dP = a + 2 b P is too: checked
    at both ends."""
    P = m.P_grid_mpa
    spans = [(P[k], P[k + 1], P[k + 1] - P[k]) for k in range(len(P) - 1)]
    for T, row in zip(m.T_grid_c, m.mu):
        for slip, cell in zip(m.slip_grid_rpm, row):
            for k, (lo, hi, width) in enumerate(spans):
                b = (cell[k + 1] - cell[k]) / width
                if cell[k] + b * lo < 0.0 or cell[k + 1] + b * hi < 0.0:
                    return T, slip, lo, hi
    return None


def _check_map(m: FrictionMap) -> None:
    grids = (("T_grid_c", m.T_grid_c), ("slip_grid_rpm", m.slip_grid_rpm), ("P_grid_mpa", m.P_grid_mpa))
    for key, grid in grids:
        if not isinstance(grid, tuple) or len(grid) < 2 or any(not isinstance(x, float) for x in grid) or \
                any(b <= a for a, b in zip(grid, grid[1:])):
            raise CalibrationError(f"friction.{key}: needs a list of at least two strictly increasing values")
    shape = tuple(len(g) for _, g in grids)
    ok = isinstance(m.mu, tuple) and len(m.mu) == shape[0] and all(
        isinstance(row, tuple) and len(row) == shape[1] and all(
            isinstance(cell, tuple) and len(cell) == shape[2] for cell in row) for row in m.mu)
    if not ok:
        raise CalibrationError(f"friction.mu: must be {shape[0]} x {shape[1]} x {shape[2]} values "
                               f"(T_grid_c x slip_grid_rpm x P_grid_mpa)")
    if (falls := torque_falls(m)) is not None:
        T, slip, lo, hi = falls
        raise CalibrationError(f"friction.mu: the torque mu P falls as the pressure rises at {T:g} degC, {slip:g} "
                               f"r/min, {lo:g}-{hi:g} MPa (the pressure for a torque needs it rising)")


def parse_calibration(text: str, origin: str = "<string>") -> TcuCalibration:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CalibrationError(f"{origin}: not valid TOML: {exc}") from None
    unknown = set(data) - {"strategy", "speed", "launch", "vehicle", "friction", "clutch"}
    if unknown:
        raise CalibrationError(f"{sorted(unknown)[0]}: unknown section")
    if set(data.get("clutch", {})) - {"CL", "CH"}:
        raise CalibrationError(f"clutch.{sorted(set(data['clutch']) - {'CL', 'CH'})[0]}: unknown section")
    parts = {name.replace("clutch.", ""): _section(data, name, cls) for name, cls in SECTIONS.items()}
    _check_map(parts["friction"])
    if parts["strategy"].stop_release_s > parts["strategy"].handover_time_s:
        raise CalibrationError("strategy.stop_release_s: must not exceed strategy.handover_time_s (the handover "
                               "margin covers the heat of the stop ramp only then)")
    return TcuCalibration(**parts)


def load_calibration(path: str | Path | None = None) -> TcuCalibration:
    path = Path(path) if path is not None else DEFAULT_CALIBRATION
    text = read_input_file(path, "calibration", CalibrationError)
    try:
        return _parse_once(text, str(path))
    except CalibrationError as exc:
        message = str(exc)  # name the file once (a TOML error already starts with it)
        raise CalibrationError(message if message.startswith(f"{path}: ") else f"{path}: {message}") from None


@functools.lru_cache(maxsize=8)
def _parse_once(text: str, origin: str) -> TcuCalibration:
    """:func:`parse_calibration`, once per text (the calibration is immutable): a sweep of short closed-loop runs
    would otherwise spend a good part of each run parsing the same file."""
    return parse_calibration(text, origin)


def _toml_value(x: Any) -> str:
    if isinstance(x, str):
        return '"' + x.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in x) + "]"
    return repr(float(x)) if isinstance(x, float) else str(x)


def dump_calibration(raw: dict, header: str = "") -> str:
    """TOML text of a calibration given as ``{section: {key: {value, unit, source, how}}}`` (sections may be
    dotted, e.g. ``clutch.CL``), in the order given; ``header`` becomes leading comment lines."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    for section, entries in raw.items():
        lines += ["", f"[{section}]"]
        for key, e in entries.items():
            fields_ = ", ".join(f"{k} = {_toml_value(e[k])}" for k in ("value", "unit", "source", "how") if k in e)
            lines.append(f"{key} = {{ {fields_} }}")
    return "\n".join(lines) + "\n"


def raw_sections(path: str | Path | None = None) -> dict:
    """The calibration file as ``{section: {key: entry}}`` with dotted section names (for rewriting it)."""
    data = tomllib.loads(Path(path or DEFAULT_CALIBRATION).read_text(encoding="utf-8"))
    return {name: dict(data[name] if "." not in name else data["clutch"][name.split(".")[1]]) for name in SECTIONS}
