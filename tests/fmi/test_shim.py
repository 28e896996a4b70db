"""dsg-hil's shim, the linux64 binary of the FMUs (dsg_hil/fmi/shim.c): PythonFMU's binary beside it, every FMI 2.0
function forwarded, a call the slave refused returned as fmi2Error; compiled once per source into the user's cache;
without a C compiler the FMU keeps PythonFMU's binary and says so."""

from __future__ import annotations

import ctypes
import sys
import zipfile
from pathlib import Path

import pytest

from dsg_hil.fmi import export
from dsg_hil.fmi.export import REAL_SUFFIX, compiler, export_fmu, has_shim, shim_binary

from .conftest import OPEN_INSTANCE, run_python

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the shim is a Linux library")

# the functions of an FMI 2.0 co-simulation FMU (fmi2Functions.h: the common ones and the co-simulation ones)
FMI2_FUNCTIONS = [
    "fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging", "fmi2Instantiate", "fmi2FreeInstance",
    "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset",
    "fmi2GetReal", "fmi2GetInteger", "fmi2GetBoolean", "fmi2GetString", "fmi2SetReal", "fmi2SetInteger",
    "fmi2SetBoolean", "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate", "fmi2GetDirectionalDerivative",
    "fmi2SetRealInputDerivatives", "fmi2GetRealOutputDerivatives", "fmi2DoStep", "fmi2CancelStep", "fmi2GetStatus",
    "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus", "fmi2GetStringStatus"]


def _pythonfmu_binary() -> bytes:
    import pythonfmu

    return (Path(pythonfmu.__file__).parent / "resources" / "binaries" / "linux64" / "libpythonfmu-export.so") \
        .read_bytes()


needs_compiler = pytest.mark.skipif(compiler() is None, reason="no C compiler for x86-64 Linux")


@needs_compiler
def test_the_fmus_have_the_shim_with_pythonfmus_binary_beside_it(fmus):
    for model, path in fmus.items():
        identifier = export.MODELS[model][2]
        assert has_shim(path)
        with zipfile.ZipFile(path) as fmu:
            linux = sorted(n for n in fmu.namelist() if n.startswith("binaries/linux64/"))
            assert linux == [f"binaries/linux64/{identifier}.so", f"binaries/linux64/{identifier}{REAL_SUFFIX}"]
            assert fmu.read(linux[1]) == _pythonfmu_binary()
            shim, why = shim_binary()
            assert shim is not None and fmu.read(linux[0]) == shim.read_bytes(), why
            assert f"binaries/win64/{identifier}.dll" in fmu.namelist()  # PythonFMU's own


@needs_compiler
def test_the_shim_exports_the_fmi2_functions_and_no_finalizer():
    shim, why = shim_binary()
    assert shim is not None, why
    library = ctypes.CDLL(str(shim))  # no constructor, no dependency but the C library: harmless to load here
    assert [name for name in FMI2_FUNCTIONS if not hasattr(library, name)] == []
    # end_binary_state_at_exit passes over it: only PythonFMU's binary is finalised
    assert not hasattr(library, "finalizePythonInterpreter")
    get_version = library.fmi2GetVersion
    get_version.restype = ctypes.c_char_p
    assert get_version() == b"2.0"


@needs_compiler
def test_the_shim_is_compiled_once_per_source(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    first, why = shim_binary()
    assert first is not None and first.parent == tmp_path / "dsg-hil" / "fmi-shim", why
    monkeypatch.setattr(export, "compiler", lambda: pytest.fail("compiled a second time"))
    assert shim_binary() == (first, "")
    assert [p.name for p in first.parent.iterdir()] == [first.name]  # nothing half-written left beside it


@pytest.mark.parametrize("cc", [None, ["false"]], ids=["no compiler", "compilation fails"])
def test_without_the_shim_the_fmu_keeps_pythonfmus_binary_and_says_so(tmp_path, monkeypatch, capsys, cc):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # no shim compiled before
    monkeypatch.setattr(export, "compiler", lambda: cc)
    path = export_fmu(tmp_path / "tcu.fmu", model="tcu")
    assert not has_shim(path)
    with zipfile.ZipFile(path) as fmu:
        assert fmu.read("binaries/linux64/ecu_stub_tcu.so") == _pythonfmu_binary()
        description = fmu.read("modelDescription.xml").decode("utf-8")
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "refused calls return fmi2OK" in err[0], err
    assert ("no C compiler" if cc is None else "did not compile") in err[0]
    assert "refused calls return fmi2OK" in description
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(path)) == []


# Logging off: a refused call is fmi2Error all the same, and the host's logger hears nothing; fmi2SetDebugLogging
# turns it on. And the PythonFMU binary whose state ends at the exit is the one the shim loaded, not the shim.
LOGGING = OPEN_INSTANCE + """
from dsg_hil.fmi.host import end_binary_state_at_exit

def status(call):
    try:
        call()
    except Exception as exc:
        return str(exc)
    return None

a, vr, log = open_instance(sys.argv[1], "a", logging_on=False)
off = status(lambda: a.setReal([99999], [1.0]))
log_off = list(log)
a.setDebugLogging(True, [])
on = status(lambda: a.setReal([99999], [1.0]))
ended = end_binary_state_at_exit(a.unzipDirectory)
a.freeInstance()
print(json.dumps({"off": off, "log_off": log_off, "on": on, "log_on": log, "ended": ended}))
"""


@pytest.mark.slow
@needs_compiler
def test_a_refused_call_is_an_error_with_logging_off_and_the_shim_is_not_finalised(fmus):
    out = run_python(LOGGING, str(fmus["plant"]))
    assert "status 3 (error)" in out["off"] and out["log_off"] == []
    assert "status 3 (error)" in out["on"]
    assert out["log_on"] == [["ERROR", "fmi2SetReal: value reference 99999: no such variable; not set"]]
    assert [Path(p).name for p in out["ended"]] == [f"dsg_hil_plant{REAL_SUFFIX}"]
