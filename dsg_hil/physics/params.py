"""Model parameters: frozen dataclasses loaded from the shipped TOML file, a user's file layered on it (a partial
file gives only the keys it changes), and overrides by dotted key (``dsg-hil --set vehicle.m=9000``).

Every value in the file is an inline table ``{ value = ..., unit = "...", source = "...", <reason> = "..." }``:

* ``source = "paper"`` needs ``ref`` (where in the paper, e.g. "Table I");
* ``source = "assumed"`` needs ``why`` (the reasoning: geometry, material, typical flow ...);
* ``source = "calibrated"`` needs ``target`` (what it was fitted to, and how).

Units are SI with temperatures in degC; each field below declares its unit, and the file must state the same one.
Anything missing, unknown, mistyped, out of range or in the wrong unit raises :class:`ParameterError` naming the key.

Named configurations (:data:`CONFIGURATIONS`), accepted wherever a parameter file is (``--params table1``,
``RunConfig(params="table1")``, the pytest fixture's ``params="table1"``): ``fitted``, the shipped file, the
default (its vehicle clutches calibrated on Section V.B); ``table1``, Table I and stated assumptions alone, no
Section V.B number consumed (``data/params_table1.toml`` layered on the shipped file). A file whose name is one of
these must be given with a directory (``./table1``).
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
import dataclasses
from dataclasses import dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any, TypeVar, dataclass_transform

from ..common.errors import InputError
from ..common.files import read_input_file
from ..common.quantities import finite, quantity

__all__ = ["CONFIGURATIONS", "Circuit", "ClutchGeometry", "ClutchThermal", "ClutchThermals", "Clutches",
           "DEFAULT_CONFIGURATION", "DEFAULT_PARAMS_PATH",
           "Element", "Engine", "Friction", "Hydraulics", "Oil", "ParameterError", "Params", "Powertrain", "SOURCES",
           "Thermal", "Vehicle", "load_params", "nonneg", "p", "parameters", "params_path", "parse_params", "positive",
           "ratio", "value_of", "with_overrides"]

DEFAULT_PARAMS_PATH = Path(__file__).resolve().parent.parent / "data" / "params.toml"
# name -> file layered on the shipped one (None: the shipped file alone)
CONFIGURATIONS: dict[str, Path | None] = {"fitted": None, "table1": DEFAULT_PARAMS_PATH.with_name("params_table1.toml")}
DEFAULT_CONFIGURATION = "fitted"
SOURCES = {"paper": "ref", "assumed": "why", "calibrated": "target"}


class ParameterError(InputError):
    """A parameter file is missing, unreadable, or has a bad, missing or unknown value."""


def p(unit: str, lo: float | None = None, hi: float | None = None, lo_open: bool = False,
      whole: bool = False) -> float:
    """Declare a parameter field with its unit and allowed range [lo, hi] (lo excluded if ``lo_open``);
    ``whole``: a count, its value a whole number. The field has no default: the file must give it."""
    return field(metadata={"unit": unit, "lo": lo, "hi": hi, "lo_open": lo_open, "whole": whole})


def positive(unit: str) -> float:
    return p(unit, 0.0, None, lo_open=True)


def nonneg(unit: str) -> float:
    return p(unit, 0.0)


def ratio() -> float:
    return p("1", 0.0, 1.0, lo_open=True)


_C = TypeVar("_C")


@dataclass_transform(frozen_default=True, field_specifiers=(field, p, positive, nonneg, ratio))
def parameters(cls: type[_C]) -> type[_C]:
    """``@dataclass(frozen=True)``, and tells type checkers (PEP 681) that a field declared with :func:`p` and
    its shorthands has no default, so a missing one is an error to them as it is to the loader."""
    return dataclass(frozen=True)(cls)


@parameters
class Friction:
    """Formula (6) in its Stribeck reading (see :mod:`dsg_hil.physics.friction`)."""

    A_stribeck: float = nonneg("1")  # amplitude of the first term of (6)
    P_floor: float = positive("Pa")  # pressure floor inside (6) only
    tau_slip: float = positive("s")  # frictional memory: (6) sees the slip speed through this first-order lag


@parameters
class ClutchGeometry:
    """One wet multi-plate clutch, equation (5), and its plate pack's heat capacity."""

    N: float = p("1", 0.0, None, lo_open=True, whole=True)  # number of friction surfaces
    R_i: float = positive("m")
    R_o: float = positive("m")
    A_f: float = positive("m^2")  # piston area
    C_plate: float = positive("J/K")  # heat capacity of the plates (the component of element CL/CH in (3))


@parameters
class Clutches:
    test: ClutchGeometry  # the rig clutch of Section III.C
    CL: ClutchGeometry
    CH: ClutchGeometry


@parameters
class Oil:
    rho: float = positive("kg/m^3")
    c_p: float = positive("J/(kg*K)")


@parameters
class Circuit:
    """Oil circuit of Fig. 2: reservoir F -> pump P -> valve V (and relief RV -> F) -> clutches -> radiator R -> F.
    The cooling flow through each clutch is that clutch's own (:class:`ClutchThermal`); the rest of the valve's
    flow bypasses the clutches to R."""

    Q_pump: float = positive("m^3/s")
    Q_relief: float = nonneg("m^3/s")  # part of the pump flow returning through RV to F
    p_line: float = nonneg("Pa")  # pump delivery pressure, throttled to zero in V and RV
    eta_pump: float = ratio()


@parameters
class Element:
    """One lumped element of (2): component capacity, oil volume and its conductances."""

    C: float = positive("J/K")  # component heat capacity
    V_o: float = positive("m^3")  # oil held in the element
    K_io: float = nonneg("W/K")  # component <-> its oil
    K_iE: float = nonneg("W/K")  # component <-> environment E
    K_oE: float = nonneg("W/K")  # oil <-> environment E


@parameters
class ClutchThermal:
    """What a clutch element (CL or CH of (3)) needs besides its plate pack (Clutches.*.C_plate)."""

    h_plate_oil: float = positive("W/(m^2*K)")  # K_CL,CLo = h * N * pi (R_o^2 - R_i^2)
    Q_cool: float = nonneg("m^3/s")  # cooling oil flow through the pack (q_r of (4))
    V_o: float = positive("m^3")
    K_iE: float = nonneg("W/K")
    K_oE: float = nonneg("W/K")


@parameters
class ClutchThermals:
    test: ClutchThermal  # the rig's test clutch with the rig's lubrication (Section III.C)
    CL: ClutchThermal
    CH: ClutchThermal


@parameters
class Thermal:
    T_E: float = p("degC", -40.0, 60.0)  # environment
    clutch: ClutchThermals
    F: Element
    P: Element
    RV: Element
    V: Element
    R: Element


@parameters
class Powertrain:
    """Lumped torsional model of Fig. 6, equations (7)-(12), (14)-(17)."""

    I_e: float = positive("kg*m^2")
    I_m: float = positive("kg*m^2")
    I_in: float = positive("kg*m^2")
    I_1: float = positive("kg*m^2")
    I_2: float = positive("kg*m^2")
    I_3: float = positive("kg*m^2")
    I_4: float = positive("kg*m^2")
    I_40: float = positive("kg*m^2")
    I_50: float = positive("kg*m^2")
    I_5: float = positive("kg*m^2")
    I_R: float = positive("kg*m^2")
    K_in: float = positive("N*m/rad")
    K_a1: float = positive("N*m/rad")
    K_a2: float = positive("N*m/rad")
    K_a3: float = positive("N*m/rad")
    C_in: float = nonneg("N*m*s/rad")
    C_a1: float = nonneg("N*m*s/rad")
    C_a2: float = nonneg("N*m*s/rad")
    C_a3: float = nonneg("N*m*s/rad")
    i_a: float = positive("1")
    i_L: float = positive("1")
    i_H: float = positive("1")
    i_1: float = positive("1")
    i_b: float = positive("1")
    eta_e: float = ratio()
    eta_a: float = ratio()
    eta_L: float = ratio()
    eta_H: float = ratio()
    eta_1: float = ratio()
    eta_b: float = ratio()


@parameters
class Vehicle:
    """Road load (13)."""

    m: float = positive("kg")
    g: float = positive("m/s^2")
    f: float = nonneg("1")
    beta: float = p("rad", -0.5, 0.5)
    delta: float = p("1", 1.0)
    r_w: float = positive("m")
    A: float = positive("m^2")
    C_D: float = nonneg("1")
    rho_air: float = positive("kg/m^3")
    f_breakaway: float = nonneg("1")  # rolling resistance that holds a standing vehicle (at most f)
    v_stick: float = positive("m/s")  # rolling resistance rises from f_breakaway at rest to f at this speed
    M_brake_max: float = nonneg("N*m")  # service brake torque at the wheels at full request


@parameters
class Engine:
    """Engine with an idle governor (the paper gives no engine map)."""

    omega_idle: float = positive("rad/s")
    M_max: float = positive("N*m")  # full-load torque, flat from idle to omega_rated
    omega_rated: float = positive("rad/s")
    M_drag: float = nonneg("N*m")  # friction torque at zero fuel
    Kp_gov: float = nonneg("N*m*s/rad")
    Ki_gov: float = nonneg("N*m/rad")


@parameters
class Hydraulics:
    """Clutch pressure response: first-order lag towards the clamped command."""

    tau: float = positive("s")
    P_max: float = positive("Pa")


@parameters
class Params:
    friction: Friction
    clutch: Clutches
    oil: Oil
    circuit: Circuit
    thermal: Thermal
    powertrain: Powertrain
    vehicle: Vehicle
    engine: Engine
    hydraulics: Hydraulics
    provenance: Mapping[str, tuple[str, str]] = field(default_factory=dict, compare=False, repr=False)


def _entry(key: str, raw: Any, meta: Mapping[str, Any], provenance: dict) -> float:
    value, source, reason = quantity(key, raw, meta["unit"], SOURCES, ParameterError)
    provenance[key] = (source, reason)
    return _checked(key, value, meta)


def _checked(key: str, value: Any, meta: Mapping[str, Any]) -> float:
    """``value`` as a float: finite, within the field's declared range, whole where a count."""
    number = finite(key, value, ParameterError, meta["lo"], meta["hi"], meta["lo_open"])
    if meta.get("whole") and number != int(number):
        raise ParameterError(f"{key}: must be a whole number (a count), got {value!r}")
    return number


def _table_type(f: dataclasses.Field) -> type | None:
    """The parameter dataclass a field holds (a sub-table), else None."""
    sub = f.type if isinstance(f.type, type) else globals().get(str(f.type))
    return sub if sub is not None and is_dataclass(sub) else None


def _build(cls: type, table: Any, prefix: str, provenance: dict, base: Any = None,
           base_provenance: Mapping[str, tuple[str, str]] | None = None) -> Any:
    """``cls`` from ``table``; a key the table leaves out is taken from ``base`` (with its provenance) if given,
    else it is missing."""
    if not isinstance(table, dict):
        raise ParameterError(f"{prefix or 'file'}: expected a table, got {table!r}")
    own = [f for f in fields(cls) if f.name != "provenance"]
    unknown = set(table) - {f.name for f in own}
    if unknown:
        raise ParameterError(f"{prefix + '.' if prefix else ''}{sorted(unknown)[0]}: unknown key")
    values = {}
    for f in own:
        key = f"{prefix}.{f.name}" if prefix else f.name
        sub = _table_type(f)
        if f.name not in table and base is not None:
            values[f.name] = getattr(base, f.name)
            assert base_provenance is not None
            provenance.update((k, v) for k, v in base_provenance.items() if k == key or k.startswith(key + "."))
        elif f.name not in table:
            raise ParameterError(f"{key}: missing")
        elif sub is not None:
            values[f.name] = _build(sub, table[f.name], key, provenance,
                                    None if base is None else getattr(base, f.name), base_provenance)
        else:
            values[f.name] = _entry(key, table[f.name], f.metadata, provenance)
    return cls(**values)


def _check_consistency(params: Params) -> None:
    for name in ("test", "CL", "CH"):
        g = getattr(params.clutch, name)
        if g.R_i >= g.R_o:
            raise ParameterError(f"clutch.{name}.R_i: must be smaller than R_o ({g.R_i} >= {g.R_o})")
    c, cool = params.circuit, params.thermal.clutch
    for low in ("CL", "test"):
        if c.Q_relief + getattr(cool, low).Q_cool + cool.CH.Q_cool > c.Q_pump:
            raise ParameterError(f"circuit.Q_pump: smaller than Q_relief + thermal.clutch.{low}.Q_cool + "
                                 "thermal.clutch.CH.Q_cool")
    if params.vehicle.f_breakaway > params.vehicle.f:
        raise ParameterError(f"vehicle.f_breakaway: must not exceed f ({params.vehicle.f_breakaway} > "
                             f"{params.vehicle.f})")
    if params.engine.omega_rated <= params.engine.omega_idle:
        raise ParameterError("engine.omega_rated: must be above omega_idle")


def parse_params(text: str, origin: str = "<string>", base: Params | None = None) -> Params:
    """Parse parameter TOML text into :class:`Params` (raises :class:`ParameterError`). Without ``base`` the
    text must give every key; with it, the keys the text leaves out keep ``base``'s values and provenance."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{origin}: not valid TOML: {exc}") from None
    data.pop("meta", None)
    provenance: dict[str, tuple[str, str]] = {}
    params = _build(Params, data, "", provenance, base, None if base is None else base.provenance)
    _check_consistency(params)
    return _with_provenance(params, {key: provenance[key] for key in _leaf_keys(Params)})


def params_path(path: str | Path | None) -> Path | None:
    """The file a ``--params`` value names: a configuration's of :data:`CONFIGURATIONS` (None: the shipped file
    alone), else the path itself (None stays None)."""
    if isinstance(path, str) and path in CONFIGURATIONS:
        return CONFIGURATIONS[path]
    return None if path is None else Path(path)


def load_params(path: str | Path | None = None) -> Params:
    """Load a parameter file layered on the shipped one (``path`` None: the shipped one alone, every key given):
    the keys it gives replace the shipped values, each checked and tagged as in the shipped file. A ``str`` that
    names a configuration of :data:`CONFIGURATIONS` (``"fitted"``, ``"table1"``) loads that configuration."""
    shipped = parse_params(read_input_file(DEFAULT_PARAMS_PATH, "parameter file", ParameterError),
                           str(DEFAULT_PARAMS_PATH))
    path = params_path(path)
    if path is None:
        return shipped
    text = read_input_file(Path(path), "parameter file", ParameterError)
    return parse_params(text, str(path), base=shipped)


def with_overrides(params: Params, overrides: Mapping[str, float | str], origin: str = "params") -> Params:
    """``params`` with values replaced by dotted key (``{"vehicle.m": 9000.0}``), each in the key's unit as
    ``dsg-hil params`` lists it. A string value is a number, optionally with that unit: ``"9000"``,
    ``"9000 kg"`` or ``"9000[kg]"`` (no conversion: another unit is an error). Each value is checked as in the
    file (finite, in range, whole where a count), then the consistency checks re-run; the provenance of an
    overridden key becomes ``("override", "<origin> <key>=<value> (was <old value>, <old source>)")``.
    Errors name ``origin`` and the key (:class:`ParameterError`)."""
    provenance = dict(params.provenance)
    for key, raw in overrides.items():
        meta, old = _leaf(params, key, origin)
        number = _override_value(f"{origin} {key}", raw, meta)
        old_source = provenance.get(key, ("", ""))[0]
        provenance[key] = ("override", f"{origin} {key}={number:g} (was {old:g}, {old_source})")
        params = _replace_dotted(params, key.split("."), number)
    try:
        _check_consistency(params)
    except ParameterError as exc:
        raise ParameterError(f"{origin}: {exc}") from exc
    return _with_provenance(params, provenance)


_OVERRIDE = re.compile(r"\s*([^\s\[\]]+)\s*(?:\[([^\]]*)\]|(\S+))?\s*")


def _override_value(name: str, raw: float | str, meta: Mapping[str, Any]) -> float:
    """One override value checked as :func:`_entry` checks a file's (``raw``: a number, or its text)."""
    if isinstance(raw, str):
        match = _OVERRIDE.fullmatch(raw)
        if match is None:
            raise ParameterError(f"{name}: expected a number and optionally its unit {meta['unit']!r}, got {raw!r}")
        number, unit = match.group(1), match.group(2) if match.group(2) is not None else match.group(3)
        if unit is not None and unit.strip() != meta["unit"]:
            raise ParameterError(f"{name}: unit must be {meta['unit']!r} (no conversion), got {unit.strip()!r}")
        try:
            raw = float(number)
        except ValueError:
            raise ParameterError(f"{name}: value must be a finite number, got {number!r}") from None
    return _checked(name, raw, meta)


def value_of(params: Params, key: str, origin: str = "params") -> float:
    """The value of the parameter at the dotted ``key`` (as ``dsg-hil params`` lists it); :class:`ParameterError`
    naming ``origin`` for a key that is no parameter."""
    return _leaf(params, key, origin)[1]


def _leaf(params: Params, key: str, origin: str) -> tuple[Mapping[str, Any], float]:
    """The field metadata and the value of the parameter at the dotted ``key``."""
    obj: Any = params
    *path, name = key.split(".")
    for part in path:
        obj = getattr(obj, part, None) if part != "provenance" else None
    declared = {f.name: f for f in fields(obj)} if is_dataclass(obj) else {}
    if name not in declared or "unit" not in declared[name].metadata:
        raise ParameterError(f"{origin}: no parameter {key!r} (see 'dsg-hil params' for the keys)")
    return declared[name].metadata, getattr(obj, name)


def _replace_dotted(obj: Any, path: list[str], value: float) -> Any:
    inner = value if len(path) == 1 else _replace_dotted(getattr(obj, path[0]), path[1:], value)
    return dataclasses.replace(obj, **{path[0]: inner})


def _leaf_keys(cls: type, prefix: str = "") -> list[str]:
    """Every dotted parameter key of ``cls``, in declaration order."""
    keys = []
    for f in fields(cls):
        key = f"{prefix}.{f.name}" if prefix else f.name
        sub = _table_type(f)
        if sub is not None:
            keys += _leaf_keys(sub, key)
        elif "unit" in f.metadata:
            keys.append(key)
    return keys


def _with_provenance(params: Params, provenance: Mapping[str, tuple[str, str]]) -> Params:
    return dataclasses.replace(params, provenance=dict(provenance))
