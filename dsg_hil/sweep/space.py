"""The space of a sweep (TOML): a base scenario, distributions over its fields, the parameters (dotted keys) and the
driver's behaviour, a seeded sampler, the controller under test and the limits a run is judged by.

```toml
name = "safety"
seed = 1
n = 40                      # runs (dsg-hil sweep --n overrides)
sampler = "lhs"             # lhs (Latin hypercube) | sobol (scrambled), scipy.stats.qmc, seeded
scenario = "creep.toml"     # optional: the base scenario (relative to this file; default: the shipped one)
duration_s = 240.0          # optional: its duration

[inputs]                    # each: {uniform = [lo, hi]} | {normal = [mean, sd]} | {choice = [...]} | {fixed = x}
grade_rad = {uniform = [0.0, 0.2]}            # a scenario field: grade_rad, engine_speed_rpm, duration_s,
"initial.T_clutch_c" = {uniform = [40, 150]}  #   initial.T_clutch_c, initial.T_CL_c, initial.T_CH_c,
"params.vehicle.m" = {normal = [7840, 500]}   #   initial.T_oil_c, initial.v_mps; a parameter: params.<key>
"driver.behaviour" = {choice = ["creep", "brake_drag"]}   # a driver generator and its settings (drivers.py)
"driver.desired_speed_mps" = {uniform = [0.05, 0.4]}
fault = {choice = ["", "drop:TCU_CMD@20-20.5", "drop:PLANT_OIL_TEMP"]}  # --fault syntax ("": none)
fault_at_s = {uniform = [5, 200]}           # the window of a fault given without one: @at-(at + duration)
fault_duration_s = {uniform = [0.1, 5]}     #   (no duration: to the end of the run)

[controller]                # kind = "ecu-stub" (calibration = FILE) | "python" (target = "module:factory")
kind = "ecu-stub"           #      | "command" (argv = [..., "{bus_args}"]: one process per run, own UDP group)

[limits]                    # a run violates when (defaults in dsg_hil.sweep.verdict.LIMITS)
plate_temp_c = 250.0

[search]                    # dsg-hil sweep --search: Optuna maximises this (verdict.OBJECTIVES)
objective = "max_plate_temp_c"

[latent]                    # optional: offsets and gains on the TCU's inputs, sized by its checks (latent.py)
per_run = [0, 2]
scale = [0.1, 2.5]
```

Every error is an :class:`SpaceError` (exit 2) naming the file and the key; nothing is run or written before.
A sample is plain data (:class:`Sample`: the drawn inputs), made into a run's task by :meth:`Space.task`. The latent
faults are drawn apart from the sampler (its dimensions are those of ``[inputs]``), per run index, into the sample's
``latent`` input (:meth:`Space.with_latent`).
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ..common.errors import InputError
from ..common.files import read_input_file
from ..physics.params import ParameterError, load_params, value_of, with_overrides
from ..protocol.codec import load_dbc
from ..protocol.faults import FaultError, check_against_dbc, parse_fault
from ..sim.scenario import DEFAULT_SCENARIO, ScenarioError, parse_scenario
from .drivers import BEHAVIOURS, SETTINGS, DriverError, scenario_tables, scenario_toml
from .latent import LatentError, LatentSpace, latent_faults, parse_latent
from .verdict import LIMITS, OBJECTIVES

__all__ = ["CONTROLLERS", "FAULT_TIMING", "SAFETY_SPACE", "SAMPLERS", "SCENARIO_FIELDS", "Dist", "Space", "SpaceError",
           "load_space", "parse_space"]

SAFETY_SPACE = Path(__file__).resolve().parents[1] / "data" / "sweeps" / "safety.toml"  # the shipped space
SAMPLERS = ("lhs", "sobol")
CONTROLLERS = ("ecu-stub", "python", "command")
FAULT_TIMING = ("fault_at_s", "fault_duration_s")  # the window of a fault written without one
SCENARIO_FIELDS = ("grade_rad", "engine_speed_rpm", "duration_s", "initial.T_clutch_c", "initial.T_CL_c",
                   "initial.T_CH_c", "initial.T_oil_c", "initial.v_mps")
_TOP = {"name", "seed", "n", "sampler", "scenario", "duration_s", "inputs", "controller", "limits", "search", "latent"}


class SpaceError(InputError):
    """A sweep's space file is missing, unreadable or has a bad key or value (the message names them)."""


@dataclass(frozen=True)
class Dist:
    """One input's distribution: ``uniform`` [lo, hi], ``normal`` (mean, sd), ``choice`` of values, ``fixed``."""

    kind: str
    args: tuple[Any, ...]

    @property
    def free(self) -> bool:
        """Drawn (a dimension of the sampler), not fixed."""
        return self.kind != "fixed" and not (self.kind == "choice" and len(self.args) == 1)

    def at(self, u: float) -> Any:
        """The value at the quantile ``u`` in [0, 1) (the sampler's coordinate)."""
        if self.kind == "uniform":
            lo, hi = self.args
            return lo + (hi - lo) * u
        if self.kind == "normal":
            from scipy.stats import norm  # noqa: PLC0415 - scipy when sampling

            mean, sd = self.args
            return float(norm.ppf(min(max(u, 1e-9), 1 - 1e-9), loc=mean, scale=sd))
        if self.kind == "choice":
            return self.args[min(int(u * len(self.args)), len(self.args) - 1)]
        return self.args[0]


def _dist(key: str, raw: Any, origin: str) -> Dist:
    """The distribution of ``[inputs] key`` (a bare value is fixed)."""
    if not isinstance(raw, dict):
        return Dist("fixed", (raw,))
    if len(raw) != 1:
        raise SpaceError(f"{origin}: inputs.{key}: give one of uniform, normal, choice, fixed, got {sorted(raw)}")
    kind, value = next(iter(raw.items()))
    if kind == "fixed":
        return Dist("fixed", (value,))
    if kind == "choice":
        if not isinstance(value, list) or not value:
            raise SpaceError(f"{origin}: inputs.{key}.choice: must be a non-empty list")
        return Dist("choice", tuple(value))
    if kind not in ("uniform", "normal"):
        raise SpaceError(f"{origin}: inputs.{key}.{kind}: unknown distribution (uniform, normal, choice, fixed)")
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise SpaceError(f"{origin}: inputs.{key}.{kind}: must be two finite numbers, got {value!r}")
    a, b = (float(v) for v in value)
    if kind == "uniform" and not a <= b:
        raise SpaceError(f"{origin}: inputs.{key}.uniform: low {a:g} above high {b:g}")
    if kind == "normal" and not b > 0:
        raise SpaceError(f"{origin}: inputs.{key}.normal: the standard deviation must be > 0, got {b:g}")
    return Dist(kind, (a, b))


@dataclass(frozen=True)
class Space:
    """A loaded, checked space: what :func:`dsg_hil.sweep.run_sweep` runs. ``base``: the base scenario's TOML
    tables; ``inputs``: name -> :class:`Dist`; ``controller``: plain data for the worker (a calibration's text,
    not its path)."""

    name: str
    origin: str
    seed: int
    n: int
    sampler: str
    base: Mapping[str, Any]
    inputs: Mapping[str, Dist]
    controller: Mapping[str, Any]
    limits: Mapping[str, float]
    objective: str
    defaults: Mapping[str, Any] = field(default_factory=dict)  # values of inputs left out (the base's)
    latent: LatentSpace | None = None  # [latent]: sensor offsets and gains drawn per run (latent.py)

    @property
    def digest(self) -> str:
        """What makes the runs (sampler, seed, base, distributions, controller, limits): equal digests draw the same
        run for the same index."""
        what = [self.sampler, self.seed, self.base, {k: [d.kind, list(d.args)] for k, d in self.inputs.items()},
                self.controller, self.limits]
        if self.latent is not None:  # (a space without one keeps its digest)
            what.append(self.latent.as_data())
        return hashlib.sha1(json.dumps(what, sort_keys=True, default=str).encode()).hexdigest()[:16]

    @property
    def stable_prefix(self) -> bool:
        """The first ``n`` runs are the same whatever the total: true of Sobol's sequence (and of a space that draws
        nothing), not of a Latin hypercube (its strata are ``1/n`` wide)."""
        return self.sampler == "sobol" or not self.free

    @property
    def free(self) -> list[str]:
        """The drawn inputs, in file order: the sampler's dimensions."""
        return [k for k, d in self.inputs.items() if d.free]

    def samples(self, n: int | None = None) -> list[dict[str, Any]]:
        """``n`` (default: the file's) input sets from the seeded sampler: the same file gives the same runs."""
        n = self.n if n is None else n
        free = self.free
        units = _unit_points(self.sampler, len(free), n, self.seed) if free else [[] for _ in range(n)]
        out = []
        for index, u in enumerate(units):
            values = {k: d.args[0] for k, d in self.inputs.items() if not d.free}
            values |= {k: _plain(self.inputs[k].at(float(x))) for k, x in zip(free, u)}
            out.append(self.with_latent(index, {k: values[k] for k in self.inputs}))
        return out

    def with_latent(self, index: int, values: Mapping[str, Any]) -> dict[str, Any]:
        """``values`` with run ``index``'s latent faults as the input ``latent`` (a space without ``[latent]``:
        unchanged): a function of the seed, the index and the run's duration only."""
        if self.latent is None:
            return dict(values)
        duration = values.get("duration_s", self.base.get("duration_s"))
        if not isinstance(duration, (int, float)):
            duration = parse_scenario(scenario_toml(scenario_tables(self.base, {}))).duration_s
        return {**values, "latent": self.latent.draw(self.seed, index, float(duration))}

    def task(self, index: int, values: Mapping[str, Any]) -> dict[str, Any]:
        """A run as plain data (what a worker gets): ``run_id``, ``inputs``, the scenario TOML text, the parameter
        overrides by dotted key, the ``--fault`` strings, the controller, the limits."""
        scenario = scenario_tables(self.base, values)
        params = {k.removeprefix("params."): float(v) for k, v in values.items() if k.startswith("params.")}
        faults = [_timed(f, values) for f in _faults(values.get("fault", "")) if f] + \
            latent_faults(values.get("latent"))
        digest = hashlib.sha1(json.dumps([values, self.controller], sort_keys=True, default=str).encode())
        return {"run_id": f"r{index:05d}-{digest.hexdigest()[:8]}", "index": index, "inputs": dict(values),
                "scenario": scenario_toml(scenario), "params": params, "faults": faults,
                "controller": dict(self.controller), "limits": dict(self.limits), "space": self.name}

    def with_parameters(self, values: Mapping[str, float]) -> Space:
        """This space with parameters fixed by dotted key (``dsg-hil sweep --set``); a parameter the space
        draws is a :class:`SpaceError` (fix it in the file: the sampler's dimensions would change)."""
        drawn = [k for k in values if f"params.{k}" in self.inputs and self.inputs[f"params.{k}"].free]
        if drawn:
            raise SpaceError(f"--set {drawn[0]}: {self.origin} draws params.{drawn[0]} (change it in the file)")
        fixed = {f"params.{k}": Dist("fixed", (float(v),)) for k, v in values.items()}
        return replace(self, inputs={**self.inputs, **fixed})

    def tasks(self, n: int | None = None) -> list[dict[str, Any]]:
        return [self.task(i, values) for i, values in enumerate(self.samples(n))]


def _faults(raw: Any) -> list[str]:
    return [raw] if isinstance(raw, str) else list(raw)


def _timed(fault: str, values: Mapping[str, Any]) -> str:
    """``fault`` (``--fault`` syntax) with the drawn window ``@at-(at + duration)`` if it has none and the space
    draws ``fault_at_s`` (``fault_duration_s`` left out: to the end of the run)."""
    head, sep, options = fault.partition(",")
    if "@" in head or "fault_at_s" not in values:
        return fault
    start = float(values["fault_at_s"])
    end = f"{start + float(values['fault_duration_s']):.3f}" if "fault_duration_s" in values else ""
    return f"{head}@{start:.3f}-{end}{sep}{options}"


def _plain(value: Any) -> Any:
    """A value as TOML/JSON/Parquet take it (numpy scalars to Python, whole floats of a choice kept)."""
    return value.item() if hasattr(value, "item") else value


def _unit_points(sampler: str, d: int, n: int, seed: int) -> list[list[float]]:
    import warnings  # noqa: PLC0415

    from scipy.stats import qmc  # noqa: PLC0415 - scipy when sampling

    engine = qmc.LatinHypercube(d, seed=seed) if sampler == "lhs" else qmc.Sobol(d, scramble=True, seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Sobol's balance warning for n not a power of 2
        return engine.random(n).tolist() if n > 0 else []


def _table(data: Mapping[str, Any], key: str, origin: str) -> dict[str, Any]:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise SpaceError(f"{origin}: {key}: must be a table")
    return value


def _whole(data: Mapping[str, Any], key: str, default: int, origin: str, lo: int = 0) -> int:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < lo:
        raise SpaceError(f"{origin}: {key}: must be a whole number >= {lo}, got {value!r}")
    return value


def parse_space(text: str, origin: str = "<string>", root: Path | None = None) -> Space:
    """A space from its TOML text (``root``: where relative paths in it are; default the current directory)."""
    root = Path(".") if root is None else root
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpaceError(f"{origin}: not valid TOML: {exc}") from None
    unknown = sorted(set(data) - _TOP)
    if unknown:
        raise SpaceError(f"{origin}: {unknown[0]}: unknown key")
    sampler = data.get("sampler", "lhs")
    if sampler not in SAMPLERS:
        raise SpaceError(f"{origin}: sampler: {sampler!r} is not one of {', '.join(SAMPLERS)}")
    base = _base(data, origin, root)
    inputs = {str(k): _dist(str(k), v, origin) for k, v in _table(data, "inputs", origin).items()}
    for key in inputs:
        _check_input(key, inputs[key], origin)
    controller = _controller(_table(data, "controller", origin), origin, root)
    limits = dict(LIMITS)
    for key, value in _table(data, "limits", origin).items():
        if key not in LIMITS:
            raise SpaceError(f"{origin}: limits.{key}: unknown limit ({', '.join(LIMITS)})")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise SpaceError(f"{origin}: limits.{key}: must be a number, got {value!r}")
        limits[key] = float(value)
    search = _table(data, "search", origin)
    if set(search) - {"objective"}:
        raise SpaceError(f"{origin}: search.{sorted(set(search) - {'objective'})[0]}: unknown key")
    objective = search.get("objective", "max_plate_temp_c")
    if objective not in OBJECTIVES:
        raise SpaceError(f"{origin}: search.objective: {objective!r} is not one of {', '.join(OBJECTIVES)}")
    latent = None
    if "latent" in data:
        try:
            latent = parse_latent(_table(data, "latent", origin))
        except LatentError as exc:
            raise SpaceError(f"{origin}: {exc}") from exc
    space = Space(name=str(data.get("name", Path(origin).stem)), origin=origin,
                  seed=_whole(data, "seed", 0, origin), n=_whole(data, "n", 20, origin), sampler=sampler,
                  base=base, inputs=inputs, controller=controller, limits=limits, objective=objective, latent=latent)
    _check_corners(space)
    return space


def _base(data: Mapping[str, Any], origin: str, root: Path) -> dict[str, Any]:
    """The base scenario's TOML tables (checked as a scenario), with the space's duration."""
    path = DEFAULT_SCENARIO if "scenario" not in data else root / str(data["scenario"])
    try:
        text = read_input_file(path, "scenario", ScenarioError)
        parse_scenario(text, str(path))
    except ScenarioError as exc:
        raise SpaceError(f"{origin}: scenario: {exc}") from exc
    base = tomllib.loads(text)
    if "duration_s" in data:
        base["duration_s"] = data["duration_s"]
    return base


def _check_input(key: str, dist: Dist, origin: str) -> None:
    where = f"{origin}: inputs.{key}"
    if key.startswith("params."):
        if dist.kind == "choice" and not all(isinstance(v, (int, float)) for v in dist.args):
            raise SpaceError(f"{where}: a parameter takes numbers")
        return  # its key, then its corner values: in _check_corners
    if key.startswith("driver."):
        name = key.removeprefix("driver.")
        if name not in SETTINGS:
            raise SpaceError(f"{where}: unknown driver setting ({', '.join(SETTINGS)})")
        if name == "behaviour" and any(v not in BEHAVIOURS for v in dist.args):
            raise SpaceError(f"{where}: behaviours are {', '.join(BEHAVIOURS)}")
        return
    if key == "fault":
        db = load_dbc()  # the shipped DBC, which every run of a sweep talks
        for value in dist.args:
            for text in _faults(value):
                if text:
                    try:
                        check_against_dbc(parse_fault(text), db, f"--fault {text!r}")
                    except FaultError as exc:
                        raise SpaceError(f"{where}: {exc}") from exc
        return
    if key in FAULT_TIMING:
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0 for v in _corners(dist)):
            raise SpaceError(f"{where}: must be seconds >= 0")
        return
    if key not in SCENARIO_FIELDS:
        raise SpaceError(f"{where}: unknown input (a scenario field {', '.join(SCENARIO_FIELDS)}; params.KEY; "
                         f"driver.SETTING; fault, {', '.join(FAULT_TIMING)})")


def _corners(dist: Dist) -> list[Any]:
    if dist.kind == "uniform":
        return list(dist.args)
    if dist.kind == "normal":
        return [dist.at(0.001), dist.at(0.999)]
    return list(dist.args)


def _check_corners(space: Space) -> None:
    """Every input's extreme values make a valid scenario and valid parameters (errors name the input)."""
    plain = {k: d.args[0] for k, d in space.inputs.items()}
    base_params = load_params()
    for key in space.inputs:  # a key that is no parameter, named as itself (not as the first input's corner)
        if key.startswith("params."):
            try:
                value_of(base_params, key.removeprefix("params."), f"inputs.{key}")
            except ParameterError as exc:
                raise SpaceError(f"{space.origin}: {exc}") from exc
    for key, dist in space.inputs.items():
        for value in _corners(dist):
            values = {**plain, key: value}
            try:
                task = space.task(0, values)
                parse_scenario(task["scenario"], f"inputs.{key}")
                with_overrides(base_params, task["params"], origin=f"inputs.{key}")
            except (ScenarioError, ParameterError) as exc:
                raise SpaceError(f"{space.origin}: inputs.{key} = {value!r}: {exc}") from exc
            except DriverError as exc:
                raise SpaceError(f"{space.origin}: {exc}") from exc


def _controller(table: Mapping[str, Any], origin: str, root: Path) -> dict[str, Any]:
    kind = table.get("kind", "ecu-stub")
    allowed = {"ecu-stub": {"kind", "calibration"}, "python": {"kind", "target"}, "command": {"kind", "argv"}}
    if kind not in CONTROLLERS:
        raise SpaceError(f"{origin}: controller.kind: {kind!r} is not one of {', '.join(CONTROLLERS)}")
    extra = sorted(set(table) - allowed[kind])
    if extra:
        raise SpaceError(f"{origin}: controller.{extra[0]}: unknown key for kind {kind!r}")
    if kind == "ecu-stub":
        if "calibration" not in table:
            return {"kind": kind}
        path = root / str(table["calibration"])
        text = read_input_file(path, "calibration", SpaceError)
        from ecu_stub.calibration import CalibrationError, parse_calibration  # noqa: PLC0415

        try:
            parse_calibration(text, str(path))
        except CalibrationError as exc:
            raise SpaceError(f"{origin}: controller.calibration: {exc}") from exc
        return {"kind": kind, "calibration": text, "calibration_file": str(path)}
    if kind == "python":
        target = table.get("target")
        if not isinstance(target, str) or ":" not in target:
            raise SpaceError(f"{origin}: controller.target: 'module:factory' expected, got {target!r}")
        return {"kind": kind, "target": target}
    argv = table.get("argv")
    if not isinstance(argv, list) or not argv or not all(isinstance(a, str) for a in argv):
        raise SpaceError(f"{origin}: controller.argv: a non-empty list of strings expected, got {argv!r}")
    return {"kind": kind, "argv": list(argv)}


def load_space(path: str | Path) -> Space:
    """Load and check a space file (:class:`SpaceError` naming the file and key)."""
    path = Path(path)
    return parse_space(read_input_file(path, "sweep space", SpaceError), str(path), path.parent)

