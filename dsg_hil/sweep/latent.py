"""Latent sensor faults: offsets and gains on the TCU's inputs, sized by what its plausibility checks let through.

A sweep space's ``[latent]`` section draws, for each run, up to two such faults on distinct signals::

    [latent]
    per_run = [0, 2]             # how many per run: a whole number drawn uniformly from [lo, hi] (at most 2)
    scale = [0.1, 2.5]           # magnitude: a multiple of the signal's detection threshold, drawn uniformly
    kinds = ["offset", "gain"]   # offset: the error added; gain: 1 +- the threshold's share of the nominal value
    at_zero = 0.25               # the share of faults present from t = 0; the others start uniformly over the run
    signals = ["PLANT_OIL_TEMP.T_OilCL", ...]   # optional: default all of LATENT_SIGNALS

Both signs are drawn with equal probability. A drawn fault is a ``--fault`` string of kind ``offset`` or ``gain`` to
the end of the run (``offset:PLANT_OIL_TEMP.T_OilCL@0-,value=-12``); a run's faults are the sample's ``latent``
input (``"; "``-separated, the table's column ``in.latent``) and join its frame faults. The draw depends only on
the space's seed and the run's index, so a space gives the same latent faults for every ``n`` (and a search
trial, not steered by the optimiser, those of its index).

**The detection thresholds** (:func:`thresholds`) are the steady error each check lets through at a nominal
operating point, read from the TCU's constants (``ecu_stub.sensor_checks``, ``ecu_stub.plausibility``) and its
shipped calibration, with the operating range's (``dsg_hil.sim.operating_range``) lowest idle and highest creep
speed as the nominal point:

* ``T_OilCL``, ``T_OilCH``: the oil check's ``OIL_TOL_K`` (10 K); nominal the safety temperature ``T_safe_c``.
  ``T_Sump`` has no check of its own (it enters the oil balance with the weight cooling/(K + cooling)): the same.
* ``ClutchInputSpeed``: the input speed check's ``N_ABS_RPM + N_REL x`` the shaft-I speed at the lowest idle
  (idle / ``input_ratio``), nominal that speed; ``EngineSpeed``: the same check seen from the engine,
  ``input_ratio`` times it, nominal the idle.
* ``P_CL``, ``P_CH``: the pressure check's ``P_ABS_MPA + P_REL x`` half the command range (``P_max_mpa / 2``, about
  a creep's pressure), nominal that pressure.
* ``VehicleSpeed``: the speed vote's pair tolerance ``REL_TOL x`` the top creep speed plus the distance bound over the
  time a pair stays disagreeing (``DISTANCE_M / HEAL_S``: a steady error below it is not kept replaced), nominal the
  top creep speed; ``CLOutputSpeed``, ``CHOutputSpeed``: the same speed error at each clutch output (the
  calibration's ``speed_ratio_m``). The vote replaces only VehicleSpeed: an output speed's error is never detected,
  its scale is the vote's.

A gain's threshold is the offset's share of the nominal value: ``gain = 1 +- multiple x offset / nominal``.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from ecu_stub import plausibility, sensor_checks
from ecu_stub.calibration import TcuCalibration, load_calibration

from ..common.errors import InputError
from ..protocol.codec import load_dbc
from ..protocol.faults import FaultError, check_against_dbc, parse_fault
from ..sim.operating_range import OPERATING_RANGE

__all__ = ["KINDS", "LATENT_SIGNALS", "LatentError", "LatentSpace", "Threshold", "latent_faults", "largest_multiple",
           "multiple", "parse_latent", "thresholds"]

LATENT_SIGNALS = ("PLANT_OIL_TEMP.T_OilCL", "PLANT_OIL_TEMP.T_OilCH", "PLANT_OIL_TEMP.T_Sump",
                  "PLANT_SPEEDS.ClutchInputSpeed", "PLANT_SPEEDS.CLOutputSpeed", "PLANT_SPEEDS.CHOutputSpeed",
                  "PLANT_ENGINE.EngineSpeed", "PLANT_VEHICLE.VehicleSpeed", "PLANT_PRESSURE.P_CL",
                  "PLANT_PRESSURE.P_CH")  # what the TCU reads of the plant and checks or predicts with
KINDS = ("offset", "gain")
MAX_PER_RUN = 2
_KEYS = ("per_run", "scale", "kinds", "at_zero", "signals")
_RPM_TO_RAD_S = math.pi / 30.0


class LatentError(InputError):
    """A ``[latent]`` section has a bad key or value (the space wraps it with its file's name)."""


@dataclass(frozen=True)
class Threshold:
    """A signal's detection threshold: ``offset`` the steady error its check lets through at ``nominal`` (both in
    the signal's DBC unit), ``check`` what checks it."""

    offset: float
    nominal: float
    check: str

    @property
    def gain(self) -> float:
        """The gain error (|gain - 1|) whose error at the nominal value is ``offset``."""
        return self.offset / self.nominal


def thresholds(calibration: TcuCalibration | None = None) -> dict[str, Threshold]:
    """Each of :data:`LATENT_SIGNALS`'s threshold (module docstring), from the TCU's constants as they are now and
    ``calibration`` (default: the shipped one)."""
    cal = load_calibration() if calibration is None else calibration
    idle = OPERATING_RANGE["engine_speed_rpm"].lo
    v_top = OPERATING_RANGE["driver.desired_speed_mps"].hi
    i_a = cal.vehicle.input_ratio
    shaft = idle / i_a
    n_tol = sensor_checks.N_ABS_RPM + sensor_checks.N_REL * shaft
    oil = Threshold(sensor_checks.OIL_TOL_K, cal.strategy.T_safe_c, "oil balance (OIL_TOL_K)")
    p_nominal = cal.speed.P_max_mpa / 2.0
    pressure = Threshold(sensor_checks.P_ABS_MPA + sensor_checks.P_REL * p_nominal, p_nominal,
                         "pressure vs command (P_ABS_MPA + P_REL P)")
    v_tol = plausibility.REL_TOL * v_top + plausibility.DISTANCE_M / plausibility.HEAL_S
    vote = "speed vote (REL_TOL v + DISTANCE_M / HEAL_S)"

    def output(clutch: str) -> Threshold:
        per_rpm = cal.clutch(clutch).speed_ratio_m * _RPM_TO_RAD_S  # m/s per r/min
        return Threshold(v_tol / per_rpm, v_top / per_rpm, vote + ", never replaced")

    return {"PLANT_OIL_TEMP.T_OilCL": oil, "PLANT_OIL_TEMP.T_OilCH": oil,
            "PLANT_OIL_TEMP.T_Sump": Threshold(oil.offset, oil.nominal, "none (the oil check's tolerance)"),
            "PLANT_SPEEDS.ClutchInputSpeed": Threshold(n_tol, shaft, "input vs engine (N_ABS_RPM + N_REL n)"),
            "PLANT_SPEEDS.CLOutputSpeed": output("CL"), "PLANT_SPEEDS.CHOutputSpeed": output("CH"),
            "PLANT_ENGINE.EngineSpeed": Threshold(i_a * n_tol, idle, "input vs engine, times input_ratio"),
            "PLANT_VEHICLE.VehicleSpeed": Threshold(v_tol, v_top, vote),
            "PLANT_PRESSURE.P_CL": pressure, "PLANT_PRESSURE.P_CH": pressure}


@dataclass(frozen=True)
class LatentSpace:
    """A checked ``[latent]`` section (module docstring)."""

    signals: tuple[str, ...] = LATENT_SIGNALS
    kinds: tuple[str, ...] = KINDS
    per_run: tuple[int, int] = (0, MAX_PER_RUN)
    scale: tuple[float, float] = (0.1, 2.5)
    at_zero: float = 0.25

    def as_data(self) -> dict[str, Any]:
        """Plain data (for the space's digest)."""
        return {"signals": list(self.signals), "kinds": list(self.kinds), "per_run": list(self.per_run),
                "scale": list(self.scale), "at_zero": self.at_zero}

    def draw(self, seed: int, index: int, duration_s: float) -> str:
        """Run ``index``'s latent faults (``"; "``-separated ``--fault`` strings, ``""`` for none) in a run of
        ``duration_s``: a function of ``seed`` and ``index`` alone."""
        rng = random.Random(f"dsg-hil latent {seed} {index}")
        limits = thresholds()
        faults = []
        for signal in rng.sample(self.signals, rng.randint(*self.per_run)):
            kind, x, sign = rng.choice(self.kinds), rng.uniform(*self.scale), rng.choice((-1.0, 1.0))
            onset = 0.0 if rng.random() < self.at_zero else round(rng.uniform(0.0, duration_s), 3)
            onset = min(onset, math.nextafter(duration_s, 0.0))
            limit = limits[signal]
            value = float(f"{sign * x * limit.offset:.4g}") if kind == "offset" else round(1.0 + sign * x * limit.gain,
                                                                                           4)
            faults.append(f"{kind}:{signal}@{onset:g}-,value={value:g}")
        return "; ".join(faults)


def latent_faults(drawn: Any) -> list[str]:
    """The ``--fault`` strings of a sample's ``latent`` input (``""`` or absent: none)."""
    return [part.strip() for part in str(drawn or "").split(";") if part.strip()]


def multiple(fault: str, limits: Mapping[str, Threshold] | None = None) -> float:
    """How many times its signal's detection threshold a latent fault's error is (> 1: beyond it)."""
    spec = parse_fault(fault)
    limit = (thresholds() if limits is None else limits)[str(spec.target)]
    return abs(spec.value) / limit.offset if spec.kind == "offset" else abs(spec.value - 1.0) / limit.gain


def largest_multiple(drawn: Any) -> float | None:
    """The largest :func:`multiple` of a sample's latent faults (None: it has none)."""
    faults = latent_faults(drawn)
    if not faults:
        return None
    limits = thresholds()
    return max(multiple(f, limits) for f in faults)


def _numbers(key: str, raw: Any, whole: bool = False) -> tuple[Any, Any]:
    kinds = (int,) if whole else (int, float)
    if (not isinstance(raw, list) or len(raw) != 2 or any(isinstance(v, bool) or not isinstance(v, kinds)
                                                          or not math.isfinite(v) for v in raw)):
        raise LatentError(f"latent.{key}: must be [low, high], two {'whole ' if whole else ''}numbers, got {raw!r}")
    lo, hi = raw
    if lo > hi:
        raise LatentError(f"latent.{key}: low {lo:g} above high {hi:g}")
    return (lo, hi) if whole else (float(lo), float(hi))


def _names(key: str, raw: Any, allowed: Sequence[str]) -> tuple[str, ...]:
    if not isinstance(raw, list) or not raw or not all(isinstance(v, str) for v in raw):
        raise LatentError(f"latent.{key}: must be a non-empty list of names, got {raw!r}")
    for value in raw:
        if value not in allowed:
            raise LatentError(f"latent.{key}: {value!r} is not one of {', '.join(allowed)}")
    if len(set(raw)) != len(raw):
        raise LatentError(f"latent.{key}: a name is given twice")
    return tuple(raw)


def parse_latent(table: Mapping[str, Any]) -> LatentSpace:
    """A :class:`LatentSpace` from a ``[latent]`` table (:class:`LatentError` naming the key)."""
    unknown = sorted(set(table) - set(_KEYS))
    if unknown:
        raise LatentError(f"latent.{unknown[0]}: unknown key ({', '.join(_KEYS)})")
    values: dict[str, Any] = {}
    if "signals" in table:
        values["signals"] = _names("signals", table["signals"], LATENT_SIGNALS)
    if "kinds" in table:
        values["kinds"] = _names("kinds", table["kinds"], KINDS)
    if "per_run" in table:
        lo, hi = _numbers("per_run", table["per_run"], whole=True)
        if lo < 0 or hi > MAX_PER_RUN:
            raise LatentError(f"latent.per_run: must lie within 0-{MAX_PER_RUN}, got [{lo}, {hi}]")
        values["per_run"] = (lo, hi)
    if "scale" in table:
        lo, hi = _numbers("scale", table["scale"])
        if lo <= 0.0:
            raise LatentError(f"latent.scale: must be > 0 (a multiple of the detection threshold), got {lo:g}")
        values["scale"] = (lo, hi)
    if "at_zero" in table:
        share = table["at_zero"]
        if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0.0 <= share <= 1.0:
            raise LatentError(f"latent.at_zero: must be a share within [0, 1], got {share!r}")
        values["at_zero"] = float(share)
    latent = replace(LatentSpace(), **values)
    if latent.per_run[1] > len(latent.signals):
        raise LatentError(f"latent.per_run: {latent.per_run[1]} faults per run on distinct signals, but "
                          f"latent.signals names {len(latent.signals)}")
    try:  # every fault it can draw is one the DBC takes (the largest multiple: the widest value)
        db, limits = load_dbc(), thresholds()
        for signal in latent.signals:
            for kind in latent.kinds:
                for sign in (-1.0, 1.0):
                    x = sign * latent.scale[1]
                    value = x * limits[signal].offset if kind == "offset" else 1.0 + x * limits[signal].gain
                    if value:
                        check_against_dbc(parse_fault(f"{kind}:{signal}@0-,value={value:g}"), db,
                                          f"{latent.scale[1]:g} times {signal}'s threshold")
    except FaultError as exc:
        raise LatentError(f"latent.scale: {exc}") from exc
    return latent
