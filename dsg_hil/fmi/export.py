"""Write an FMU: a short slave module naming the model's class is packed by PythonFMU with its FMI 2.0 binary
(``pythonfmu``'s ``FmuBuilder``). The FMU holds that module, not dsg-hil: it imports ``dsg_hil`` from the Python
the host runs it in (a tool-coupling FMU), so the importing machine needs ``pip install dsg-hil[fmi]``.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

from .. import __version__
from ..common.errors import InputError, RunError
from ..common.files import check_output_path

__all__ = ["MODELS", "PARAMS_RESOURCE", "export_fmu"]

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
    return Path(built)


def _digest(module: str, cls: str) -> str:
    """The variable digest of a model's slave as this dsg-hil registers its variables."""
    import importlib  # noqa: PLC0415

    slave = getattr(importlib.import_module(module), cls)(instance_name="export", resources=None)
    return str(slave.digest)
