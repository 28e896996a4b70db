"""The compiled physics (dsg_hil.physics.jit): records of parameter groups, and the compiled code agreeing with
its own source run by the interpreter."""

from __future__ import annotations

import importlib
from dataclasses import fields, is_dataclass

import pytest

from dsg_hil.physics import jit
from dsg_hil.physics import params as params_module
from dsg_hil.physics.engine import governor
from dsg_hil.physics.friction import friction_coefficient
from dsg_hil.physics.plant import PlantInputs


def test_every_flat_parameter_group_has_an_importable_record_type():
    """numba's cache index pickles every signature a function was compiled for; reading it in a process that has
    not used a group yet needs that group's record type by name (a stale index once failed with AttributeError)."""
    flat = [c for c in vars(params_module).values() if isinstance(c, type) and is_dataclass(c)
            and all(f.type in ("float", float) for f in fields(c))]
    assert {"Friction", "Engine", "Hydraulics", "Vehicle", "Powertrain"} <= {c.__name__ for c in flat}
    module = importlib.import_module(params_module.__name__)
    for cls in flat:
        assert getattr(module, f"{cls.__name__}Record") is type(jit.record(_example(cls)))


def _example(cls):
    return cls(**{f.name: 1.0 for f in fields(cls)})


def test_record_holds_the_groups_values(params):
    rec = jit.record(params.engine)
    assert rec.Kp_gov == params.engine.Kp_gov and rec.M_max == params.engine.M_max
    assert jit.record(params.engine) is rec  # made once per group


def test_compiled_equals_its_source_interpreted(params):
    """One implementation: the machine code and the same function run by Python agree (to rounding)."""
    for n, T, P in ((0.0, 80.0, 0.3e6), (0.5, 150.0, 0.7e6), (31.4, 40.0, 0.0), (209.4, 250.0, 1.5e6)):  # rad/s, Pa
        mu = friction_coefficient(n, T, P, params.friction)
        assert abs(mu - friction_coefficient.py_func(n, T, P, params.friction)) <= 1e-15
    e = params.engine
    assert governor(e.omega_idle - 5.0, 0.0, e.omega_idle, e) == governor.py_func(e.omega_idle - 5.0, 0.0,
                                                                                  e.omega_idle, e)


def test_constants_hold_arrays_and_group_fields_by_name(params):
    """One record of a plant's constants: sub-arrays and every field of the groups, read back by name; compiled
    code given it where a group's record is expected computes the same as with the record."""
    import numpy as np
    import pytest

    from dsg_hil.physics.powertrain import road_load

    M = np.arange(6.0).reshape(2, 3)
    K = jit.constants({"M": M, "dt": 1e-3}, params.vehicle, params.engine)
    k = K[0]
    np.testing.assert_array_equal(k["M"], M)
    assert k["dt"] == 1e-3 and k["r_w"] == params.vehicle.r_w and k["Ki_gov"] == params.engine.Ki_gov
    assert road_load.dispatcher(2.0, 0.05, 0.3, k) == road_load(2.0, 0.05, 0.3, params.vehicle)
    with pytest.raises(ValueError, match="repeated names r_w"):
        jit.constants({"r_w": 1.0}, params.vehicle)


@pytest.mark.slow
def test_the_plant_step_compiled_equals_its_source_interpreted(params):
    """The plant's whole step (stick/slip of all three contacts, mu at mid-step, mean pressures) run as machine
    code and by the interpreter from the same state: the same state to rounding."""
    import numpy as np

    from dsg_hil.physics.plant import N_S, Plant, advance_steps

    plant = Plant(params, T_init=80.0)
    plant.advance(PlantInputs(P_CL_cmd=0.5e6, brake=1.0), 300)  # CL slipping against the held vehicle
    b = plant._b.copy()
    K = plant._K.view(np.recarray)  # attribute access for the interpreter (numba reads the fields by name)
    trace = np.zeros((0, 27))
    for inputs in ((0.9e6, 0.0, 0.0), (0.9e6, 0.3e6, 0.0), (0.0, 0.0, 1.0)):  # drives away, both, braked
        P_CL, P_CH, brake = inputs
        plant.advance(PlantInputs(P_CL_cmd=P_CL, P_CH_cmd=P_CH, brake=brake, grade=0.05), 40)
        advance_steps.py_func(b, K, trace, P_CL, P_CH, brake, 0.05, params.engine.omega_idle, 40)
        np.testing.assert_allclose(b[:N_S], plant._b[:N_S], rtol=1e-9, atol=1e-9)


@pytest.mark.slow
def test_the_compiled_code_is_cached_outside_the_package(tmp_path):
    """numba's cache files are not in pip's record of an install: written into the installed package, they outlive
    'pip uninstall' as a dsg_hil namespace directory that hides a later 'pip install -e .' (CI failed so). They go
    to the user's cache directory, or where NUMBA_CACHE_DIR says."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    import dsg_hil

    code = ("from dsg_hil.physics.engine import full_load_torque\n"
            "from dsg_hil.physics.params import Engine\n"
            "from dataclasses import fields\n"
            "full_load_torque(100.0, Engine(**{f.name: 1.0 for f in fields(Engine)}))\n")
    package = Path(dsg_hil.__file__).parent
    before = set(package.rglob("*.nb[ic]"))
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    for name, extra in (("xdg", {"XDG_CACHE_HOME": str(tmp_path / "xdg")}),
                        ("given", {"NUMBA_CACHE_DIR": str(tmp_path / "given")})):
        subprocess.run([sys.executable, "-c", code], env={**env, **extra}, check=True, timeout=600)
        where = tmp_path / "xdg" / "dsg-hil" / "numba" if name == "xdg" else tmp_path / "given"
        assert any(p.name.startswith("engine.full_load_torque") for p in where.rglob("*.nbi")), name
    assert set(package.rglob("*.nb[ic]")) == before
