"""What the package ships: the DBC as a real resource identical to dbc/, py.typed, one version, the wheel, and in
the wheel the closed loop compiled (setup.py), sending the same frames as the source."""

from __future__ import annotations

import importlib
import json
import os
import shutil
import subprocess
import sys
import zipfile
from importlib import metadata, resources
from pathlib import Path

import pytest

import dsg_hil
from dsg_hil.protocol.codec import DEFAULT_DBC
from dsg_hil.e2e.vcan import ENV_REQUIRE
from dsg_hil.protocol.binding import DEFAULT_BINDING, SIM_DATABASE
from dsg_hil.common.build import COMPILED, EXPECT_ENV, build, compiled_modules as loaded_modules
from dsg_hil.sweep.code import CODE_PACKAGES, digest_of

from .conftest import editable_install

ROOT = Path(__file__).resolve().parents[1]  # the checkout (or unpacked sdist) these tests came from
TOP_DBC = ROOT / "dbc" / "dsg_hil.dbc"


def test_dbc_resource_is_a_real_file_loadable_as_a_resource():
    text = DEFAULT_DBC.read_text(encoding="utf-8")
    assert text.startswith("VERSION") and "BO_ 512 TCU_CMD" in text  # not a 21-byte symlink stand-in
    assert not Path(str(DEFAULT_DBC)).is_symlink()


@pytest.mark.skipif(not TOP_DBC.exists(), reason="dbc/dsg_hil.dbc is in the source tree only (tests run from a "
                                                 "copy outside it)")
def test_dbc_resource_is_identical_to_the_top_level_dbc():
    assert DEFAULT_DBC.read_bytes() == TOP_DBC.read_bytes(), \
        "dsg_hil/data/dsg_hil.dbc and dbc/dsg_hil.dbc differ: copy one onto the other"


@pytest.mark.skipif(not TOP_DBC.exists(), reason="dbc/ is in the source tree only")
def test_simulation_database_resource_is_identical_to_the_top_level_one():
    assert SIM_DATABASE.read_bytes() == (ROOT / "dbc" / "dsg_hil_sim.dbc").read_bytes(), \
        "dsg_hil/data/dsg_hil_sim.dbc and dbc/dsg_hil_sim.dbc differ: copy one onto the other"


@pytest.mark.skipif(not TOP_DBC.exists(), reason="dbc/ is in the source tree only")
def test_binding_resource_is_identical_to_the_top_level_binding():
    assert DEFAULT_BINDING.read_bytes() == (ROOT / "dbc" / "dsg_hil.binding.toml").read_bytes(), \
        "dsg_hil/data/dsg_hil.binding.toml and dbc/dsg_hil.binding.toml differ: copy one onto the other"


@pytest.mark.skipif(not TOP_DBC.exists(), reason="dbc/ is in the source tree only")
def test_example_matrices_are_identical_to_the_top_level_ones():
    examples = sorted((ROOT / "dbc" / "examples").glob("*/*"))
    assert examples
    for path in examples:
        copy = Path(str(resources.files("dsg_hil") / "data" / "examples" / path.parent.name / path.name))
        assert copy.read_bytes() == path.read_bytes(), \
            f"dsg_hil/data/examples/{path.parent.name}/{path.name} and {path.relative_to(ROOT)} differ: copy one " \
            f"onto the other"


def test_typed_packages():
    for package in ("dsg_hil", "ecu_stub"):
        assert (resources.files(package) / "py.typed").is_file(), package


def test_version_is_single_sourced():
    assert metadata.version("dsg-hil") == dsg_hil.__version__
    pyproject = ROOT / "pyproject.toml"
    if pyproject.exists():
        text = pyproject.read_text(encoding="utf-8")
        assert 'dynamic = ["version"]' in text and 'version = { attr = "dsg_hil.__version__" }' in text


@pytest.mark.slow
def test_marker_expressions_do_not_bring_back_the_vcan_tests():
    """tests/conftest.py deselects the vcan tests for any -m that does not name vcan (not a configured -m)."""
    e2e = str(resources.files("dsg_hil.e2e"))
    args = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
            str(Path(__file__).parent / "sim" / "test_scenario.py"), e2e]
    env = {k: v for k, v in os.environ.items() if k != ENV_REQUIRE}
    for expr in ("not slow", "slow or not slow", "vcan"):
        out = subprocess.run([*args, "-m", expr], capture_output=True, text=True, env=env).stdout
        e2e_ids = [line for line in out.splitlines() if "test_end_to_end.py::" in line]
        assert bool(e2e_ids) == (expr == "vcan"), out
        assert (expr == "vcan") or "deselected" in out, out


def _wheel(out: Path, **env: str) -> Path:
    """A wheel of this checkout built into ``out`` by pip (as ``pip install .`` builds it), with ``env`` added: from a
    copy of its sources, as a fresh clone (pip builds in the tree, and a ``build/`` left there by an earlier build
    would bring its modules into the wheel)."""
    if not (ROOT / "pyproject.toml").exists():
        pytest.skip("needs the source tree")
    src = out / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".*", "build", "dist", "out", "*.egg-info", "__pycache__"))
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(src)],
                          capture_output=True, text=True, env={**os.environ, **env}, timeout=900)
    assert proc.returncode == 0, proc.stderr
    (wheel,) = out.glob("dsg_hil-*.whl")
    return wheel


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel of this checkout (the compiled modules in it where this machine has a C compiler)."""
    return _wheel(tmp_path_factory.mktemp("wheel"))


def compiled_modules() -> list[str]:
    """The modules setup.py compiles (dsg_hil.common.build.COMPILED), as paths without '.py'."""
    return [path.removesuffix(".py") for path in COMPILED]


@pytest.mark.wheel
@pytest.mark.slow
def test_wheel_ships_the_dbc_typing_license_and_extras(wheel):
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        assert zf.read("dsg_hil/data/dsg_hil.dbc") == TOP_DBC.read_bytes()
        assert zf.read("dsg_hil/data/dsg_hil.binding.toml") == DEFAULT_BINDING.read_bytes()
        info = f"dsg_hil-{dsg_hil.__version__}.dist-info"
        meta = zf.read(f"{info}/METADATA").decode()
    assert {"dsg_hil/py.typed", "ecu_stub/py.typed", "dsg_hil/data/params.toml", "dsg_hil/data/creep.toml",
            "dsg_hil/data/sweeps/safety.toml", "dsg_hil/sweep/engine.py", "dsg_hil/fmi/shim.c",
            "dsg_hil/e2e/conftest.py", "dsg_hil/e2e/test_end_to_end.py", f"{info}/licenses/LICENSE"} <= names
    assert not any(name.startswith("tests/") for name in names)
    assert "License-Expression: MIT" in meta and f"Version: {dsg_hil.__version__}" in meta
    requires = [line for line in meta.splitlines() if line.startswith("Requires-Dist: matplotlib")]
    assert "Provides-Extra: plots" in meta and requires and all('extra == "plots"' in r for r in requires)


@pytest.mark.wheel
@pytest.mark.slow
def test_wheel_holds_every_source_and_data_file_so_an_install_has_the_checkout_s_code_digest(wheel, tmp_path):
    """A sweep tells its runs' code by a digest of the packages' .py, .toml and .dbc files (dsg_hil.sweep.code):
    an install from the wheel and this checkout must give the same one (the held-out identification scenarios
    under ecu_stub/data/identification/validation were once left out of the wheel)."""
    with zipfile.ZipFile(wheel) as zf:
        zf.extractall(tmp_path, [n for n in zf.namelist() if n.split("/")[0] in CODE_PACKAGES])
    assert digest_of([tmp_path / name for name in CODE_PACKAGES]) == digest_of([ROOT / name for name in CODE_PACKAGES])


FRAME_RUNS = [(), ("--duration", "60", "--fault", "stuck:PLANT_VEHICLE.VehicleSpeed@20-23,value=0",
                   "--fault", "drop:TCU_CMD@30-31", "--fault", "drop:PLANT_OIL_TEMP@40-45")]
NEEDS_CC = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None,
                              reason="no C compiler: pip builds the pure-Python package (setup.py)")


@pytest.mark.wheel
@pytest.mark.slow
@NEEDS_CC
def test_wheel_holds_the_closed_loop_compiled_beside_its_source(wheel):
    """setup.py: each module of COMPILED as a mypyc extension module next to its source, and their shared library."""
    with zipfile.ZipFile(wheel) as zf:
        names = zf.namelist()
    for module in compiled_modules():
        assert any(n.startswith(module + ".cpython-") and n.endswith(".so") for n in names), module
        assert module + ".py" in names, module
    assert any(n.startswith("dsg_hil_compiled__mypyc.") for n in names)


@pytest.mark.wheel
@pytest.mark.slow
@NEEDS_CC
def test_a_failed_compile_gives_the_whole_pure_python_package(tmp_path):
    """setup.py's AllOrNone: a compiler that fails (CC=false) leaves no extension module at all in the wheel, and
    says so (the modules share one library: some compiled and some not would not import)."""
    with zipfile.ZipFile(_wheel(tmp_path, CC="false")) as zf:
        assert not [n for n in zf.namelist() if n.endswith(".so")]


@pytest.mark.wheel
@pytest.mark.slow
@NEEDS_CC
def test_the_codec_tests_pass_on_the_compiled_plans(wheel, tmp_path):
    """tests/protocol/test_generated_codec.py (the plans against cantools on random and corrupted frames) and
    tests/protocol/test_plan.py run on the unpacked wheel, its plan module compiled (EXPECT_ENV)."""
    site = tmp_path / "site"
    with zipfile.ZipFile(wheel) as zf:
        zf.extractall(site)
    env = {**os.environ, "PYTHONPATH": str(site), EXPECT_ENV: "1"}
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--import-mode=append",
                           str(ROOT / "tests" / "protocol" / "test_generated_codec.py"),
                           str(ROOT / "tests" / "protocol" / "test_plan.py")],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert " passed" in proc.stdout and "skipped" not in proc.stdout


@pytest.mark.wheel
@pytest.mark.slow
def test_pure_python_wheel_on_request(tmp_path):
    """DSG_HIL_PURE_PYTHON=1: no extension module in the wheel (what an editable install always is)."""
    with zipfile.ZipFile(_wheel(tmp_path, DSG_HIL_PURE_PYTHON="1")) as zf:
        assert not [n for n in zf.namelist() if n.endswith(".so")]


def test_no_compiled_module_shadows_a_source_in_the_tree():
    """An extension module next to its source is imported instead of it: one left in the checkout (an in-place
    build) would run stale code under an editable install."""
    stray = [str(p.relative_to(ROOT)) for package in ("dsg_hil", "ecu_stub") for p in (ROOT / package).rglob("*.so")]
    assert not stray, f"remove {stray}: they shadow the sources"


def _run_logged(path: Path, out: Path, *options: str) -> tuple[bytes, dict, str]:
    """``dsg-hil run`` in lock-step with the package at ``path`` first on sys.path: its log, its summary and the file
    ecu_stub.controller came from."""
    out.mkdir()
    env = {**os.environ, "PYTHONPATH": str(path)}
    subprocess.run([sys.executable, "-m", "dsg_hil", "run", "-q", "--log", str(out / "run.log"), "--summary",
                    str(out / "summary.json"), *options], check=True, env=env, cwd=out, timeout=600)
    origin = subprocess.run([sys.executable, "-c", "import ecu_stub.controller as m, dsg_hil.protocol.plan as p; "
                             "print(m.__file__ if p.COMPILED == m.__file__.endswith('.so') else 'mixed')"],
                            check=True, env=env, cwd=out, capture_output=True, text=True).stdout.strip()
    summary = json.loads((out / "summary.json").read_text())
    for key in ("wall_time_s", "realtime_factor", "interface", "command_latency_ms"):  # the machine's, not the run's
        summary.pop(key, None)
    return (out / "run.log").read_bytes(), summary, origin


@pytest.mark.wheel
@pytest.mark.slow
@NEEDS_CC
@pytest.mark.parametrize("options", FRAME_RUNS,
                         ids=["default creep", "faults"])
def test_compiled_closed_loop_sends_the_same_frames(wheel, tmp_path, options):
    """The compiled modules run the same arithmetic as the source: every frame of a lock-step run the same, bit for
    bit (the default creep, with its handovers; a run through frame faults and the TCU's fallbacks)."""
    site = tmp_path / "site"
    with zipfile.ZipFile(wheel) as zf:
        zf.extractall(site)
    log_c, summary_c, origin_c = _run_logged(site, tmp_path / "compiled", *options)
    log_p, summary_p, origin_p = _run_logged(ROOT, tmp_path / "pure", *options)
    assert origin_c.endswith(".so") and origin_p.endswith(".py"), (origin_c, origin_p)
    assert log_c.count(b"\n") > 1000
    assert log_c == log_p
    assert summary_c == summary_p


def _installed() -> tuple[metadata.Distribution, bool]:
    """dsg-hil's distribution and whether it is an editable install (:func:`tests.conftest.editable_install`)."""
    return metadata.distribution("dsg-hil"), editable_install()


def test_the_tests_import_the_installed_package_never_the_checkout():
    """The suite tests what is installed: a regular install's package from site-packages (pytest runs with
    --import-mode=importlib, which puts no test directory on sys.path), and the same in a subprocess started from
    the checkout (tests/conftest.py sets PYTHONSAFEPATH: 'python -m'/'-c' do not put the working directory first)."""
    dist, editable = _installed()
    where = {}
    for package in ("dsg_hil", "ecu_stub"):
        module = importlib.import_module(package)
        where[package] = Path(module.__file__ or "").resolve()
        if not editable:
            assert where[package] == Path(str(dist.locate_file(f"{package}/__init__.py"))).resolve(), \
                f"{package} imported from {where[package]}, not from the regular install in {dist.locate_file('')}"
    child = subprocess.run([sys.executable, "-c", "import dsg_hil, ecu_stub; print(dsg_hil.__file__); "
                            "print(ecu_stub.__file__)"], cwd=ROOT if ROOT.is_dir() else None, capture_output=True,
                           text=True, check=True).stdout.split()
    assert [Path(p).resolve() for p in child] == [where["dsg_hil"], where["ecu_stub"]]


def test_the_build_loaded_is_all_compiled_or_all_pure_and_compiled_where_expected():
    """dsg_hil.common.build: every module of COMPILED loaded from its extension module, or none (a mix does not
    import: one shared library). Where the install's own record lists them (a regular install with a C compiler)
    they are the ones loaded; with DSG_HIL_EXPECT_COMPILED set (CI's run of the shipped build) they must be."""
    loaded = loaded_modules()
    assert set(loaded.values()) in ({True}, {False}), loaded
    dist, editable = _installed()
    shipped = {str(f).split(".")[0].replace("/", ".") for f in dist.files or () if str(f).endswith(".so")
               and str(f).split("/")[0] in ("dsg_hil", "ecu_stub")}
    if not editable and shipped:
        assert shipped == set(loaded) and build() == "compiled", (shipped, loaded)
    if os.environ.get(EXPECT_ENV, "") not in ("", "0"):
        assert not editable and build() == "compiled", \
            f"{EXPECT_ENV} is set but the build loaded is {build()} (editable: {editable}): {loaded}"
