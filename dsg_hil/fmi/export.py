"""Write an FMU: a short slave module naming the model's class is packed by PythonFMU with its FMI 2.0 binary
(``pythonfmu``'s ``FmuBuilder``). The FMU holds that module, not dsg-hil: it imports ``dsg_hil`` from the Python
the host runs it in (a tool-coupling FMU), so the importing machine needs ``pip install dsg-hil[fmi]``.

The FMU's linux64 binary is dsg-hil's shim (``shim.c``, compiled here once per source, :func:`shim_binary`) with
PythonFMU's binary beside it as ``<modelIdentifier>_pythonfmu.so``: the shim forwards every call and returns
``fmi2Error`` for a call the slave refused (logged with status ``fmi2Error``), where PythonFMU's binary returns
``fmi2OK``. Without a C compiler for x86-64 Linux (and no shim compiled before) the FMU keeps PythonFMU's binary
as it is, the export says so on stderr and in the FMU's description. The other platforms' binaries (win64) are
PythonFMU's own.
"""

from __future__ import annotations

import hashlib
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

from .. import __version__
from ..common.errors import InputError, RunError
from ..common.files import check_output_path, user_cache_dir

__all__ = ["MODELS", "PARAMS_RESOURCE", "REAL_SUFFIX", "SHIM_SOURCE", "compiler", "export_fmu", "has_shim",
           "shim_binary"]

PARAMS_RESOURCE = "params.toml"  # the --params file, in the FMU's resources (PlantSlave reads it)

# model: (module, slave class, model identifier: the FMU's binary and the C name a host sees, whether the FMU
# state can be got, set and serialised: the plant's whole, not ecu-stub's controller's)
MODELS = {"plant": ("dsg_hil.fmi.plant", "PlantSlave", "dsg_hil_plant", True),
          "tcu": ("dsg_hil.fmi.tcu_slave", "TcuSlave", "ecu_stub_tcu", False)}

_SCRIPT = '''"""{model} of dsg-hil {version} as an FMI 2.0 co-simulation FMU, written by 'dsg-hil fmu export': the class
is dsg-hil's, so the host's Python needs dsg_hil installed (pip install 'dsg-hil[fmi]')."""

from dsg_hil.fmi.slave import balance_namespace
from {module} import {cls}


class {identifier}({cls}):
    exported = ("{version}", "{digest}")  # dsg-hil's version and variables: checked on the host (seal)


balance_namespace(globals(), locals())  # PythonFMU's binary releases a reference to globals() it did not take
'''


def export_fmu(out: str | Path, model: str = "plant", params: str | Path | None = None) -> Path:
    """Write the FMU of ``model`` (:data:`MODELS`) to ``out``; ``params``: a parameter file (as ``--params``) put
    into the FMU, whose values become its parameters' start values. Returns the FMU's path."""
    if model not in MODELS:
        raise InputError(f"model {model!r}: one of {', '.join(MODELS)}")
    out = Path(out)
    if out.suffix != ".fmu":
        raise InputError(f"--out {out}: an FMU's file name ends in .fmu")
    check_output_path("--out", str(out))
    if params is not None:
        from ..physics.params import load_params, params_path  # noqa: PLC0415

        load_params(params)  # checked here, not on the host
        params = params_path(params)  # a configuration's name ('fitted', 'table1'): its file goes in
    try:
        from pythonfmu import FmuBuilder  # noqa: PLC0415 - the fmi extra, when an FMU is written
    except ImportError as exc:
        raise InputError(f"writing an FMU needs the fmi extra: pip install 'dsg-hil[fmi]' ({exc})") from exc
    module, cls, identifier, state = MODELS[model]
    digest = _digest(module, cls)
    with tempfile.TemporaryDirectory(prefix="dsg_hil_fmu_") as tmp:
        script = Path(tmp) / "src" / f"{identifier}.py"
        script.parent.mkdir()
        script.write_text(_SCRIPT.format(model=model, version=__version__, module=module, cls=cls,
                                         identifier=identifier, digest=digest), encoding="utf-8")
        project_files = []
        if params is not None:
            project_files.append(Path(tmp) / PARAMS_RESOURCE)
            shutil.copyfile(params, project_files[0])
        try:
            built = FmuBuilder.build_FMU(script, dest=out, project_files=project_files, canGetAndSetFMUstate=state,
                                         canSerializeFMUstate=state)
        except (OSError, ValueError, ImportError) as exc:
            raise RunError(f"cannot write the FMU {out}: {exc}") from exc
        finally:  # the builder imports the script as a top-level module, from its folder
            sys.modules.pop(identifier, None)
            if str(script.parent) in sys.path:
                sys.path.remove(str(script.parent))
    shim, why = shim_binary()
    if shim is not None:
        _put_shim(Path(built), identifier, shim)
    else:
        _note_without_shim(Path(built), why)
        print(f"dsg-hil fmu export: {why}: {NO_SHIM}", file=sys.stderr)
    return Path(built)


def _digest(module: str, cls: str) -> str:
    """The variable digest of a model's slave as this dsg-hil registers its variables."""
    import importlib  # noqa: PLC0415

    slave = getattr(importlib.import_module(module), cls)(instance_name="export", resources=None)
    return str(slave.digest)


# ---- the linux64 shim ---------------------------------------------------------------------------------------------
SHIM_SOURCE = Path(__file__).with_name("shim.c")
REAL_SUFFIX = "_pythonfmu.so"  # PythonFMU's binary beside the shim: binaries/linux64/<modelIdentifier> + this
NO_SHIM = ("the FMU's linux64 binary is PythonFMU's own, whose refused calls return fmi2OK (logged with status "
           "fmi2Error)")
_CFLAGS = ["-std=c99", "-O2", "-shared", "-fPIC", "-fvisibility=hidden"]
_ELF_X86_64 = 62  # e_machine of an x86-64 ELF file


def compiler() -> list[str] | None:
    """The C compiler (a command line) the shim is compiled with: the one Python was built with (sysconfig's
    ``CC``) where this machine has it, else ``cc``; None where there is neither, or the machine is not x86-64
    Linux (the FMU's linux64 binary is x86-64 code)."""
    if not sys.platform.startswith("linux") or platform.machine() not in ("x86_64", "AMD64"):
        return None
    configured = shlex.split(str(sysconfig.get_config_var("CC") or ""))
    if configured and shutil.which(configured[0]):
        return configured
    return ["cc"] if shutil.which("cc") else None


def shim_binary() -> tuple[Path | None, str]:
    """The compiled shim (compiled into the user's cache the first time, one file per digest of ``shim.c`` and its
    flags), and ``""``; or None and why there is none (no compiler, a failed compilation)."""
    source = SHIM_SOURCE.read_bytes()
    key = hashlib.sha256(source + " ".join(_CFLAGS).encode()).hexdigest()[:16]  # the source and how it is compiled
    path = user_cache_dir("fmi-shim") / f"shim-{key}.so"
    if _is_x86_64_elf(path):
        return path, ""
    cc = compiler()
    if cc is None:
        return None, "no C compiler for x86-64 Linux to compile its shim"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=path.parent, prefix=".build-") as tmp:
            out = Path(tmp) / path.name
            done = subprocess.run([*cc, *_CFLAGS, "-o", str(out), str(SHIM_SOURCE), "-ldl"], capture_output=True,
                                  text=True, timeout=300)
            if done.returncode != 0 or not _is_x86_64_elf(out):
                last = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
                return None, f"its shim did not compile ({shlex.join(cc)}: {last})"
            os.replace(out, path)  # whole, or not there: another export may compile it at the same time
    except (OSError, subprocess.SubprocessError) as exc:
        return None, f"its shim did not compile ({exc})"
    return path, ""


def _is_x86_64_elf(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            head = f.read(20)
    except OSError:
        return False
    return len(head) == 20 and head[:4] == b"\x7fELF" and int.from_bytes(head[18:20], "little") == _ELF_X86_64


def _rewrite(fmu: Path, change: Callable[[str, bytes], list[tuple[str, bytes]]]) -> None:
    """Write the FMU ``fmu`` again, each member through ``change(name, data) -> [(name, data), ...]``."""
    tmp = fmu.with_name(fmu.name + ".tmp")
    with zipfile.ZipFile(fmu) as old, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as new:
        for info in old.infolist():
            for name, data in change(info.filename, old.read(info)):
                member = zipfile.ZipInfo(name, date_time=info.date_time)
                member.external_attr = info.external_attr  # the file's mode
                new.writestr(member, data, zipfile.ZIP_DEFLATED)
    os.replace(tmp, fmu)


def _put_shim(fmu: Path, identifier: str, shim: Path) -> None:
    """The shim as the FMU's linux64 binary, PythonFMU's beside it (:data:`REAL_SUFFIX`)."""
    binary = f"binaries/linux64/{identifier}.so"

    def change(name: str, data: bytes) -> list[tuple[str, bytes]]:
        if name != binary:
            return [(name, data)]
        return [(binary, shim.read_bytes()), (f"binaries/linux64/{identifier}{REAL_SUFFIX}", data)]

    _rewrite(fmu, change)


def _note_without_shim(fmu: Path, why: str) -> None:
    """The FMU's description says that its refused calls return fmi2OK."""
    def change(name: str, data: bytes) -> list[tuple[str, bytes]]:
        if name != "modelDescription.xml":
            return [(name, data)]
        note = f" Written without dsg-hil's shim ({why}): {NO_SHIM}.".replace("&", "&amp;").replace('"', "&quot;")
        text = re.sub(r'(<fmiModelDescription\b[^>]*?\bdescription="[^"]*)"',
                      lambda m: m.group(1) + note.replace("<", "&lt;") + '"', data.decode("utf-8"), count=1)
        return [(name, text.encode("utf-8"))]

    _rewrite(fmu, change)


def has_shim(fmu: str | Path) -> bool:
    """Whether the FMU ``fmu`` has dsg-hil's shim as its linux64 binary (PythonFMU's beside it)."""
    with zipfile.ZipFile(fmu) as z:
        return any(name.startswith("binaries/linux64/") and name.endswith(REAL_SUFFIX) for name in z.namelist())
