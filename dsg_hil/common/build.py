"""Which build of dsg-hil runs: the regular install compiles the modules of a control period with mypyc
(``setup.py`` reads :data:`COMPILED` from this file), an editable install or ``DSG_HIL_PURE_PYTHON=1`` leaves them
pure Python. ``dsg-hil --version`` says which; the tests of the shipped build require ``compiled`` (CI sets
:data:`EXPECT_ENV`)."""

from __future__ import annotations

import importlib
from importlib.machinery import EXTENSION_SUFFIXES

__all__ = ["COMPILED", "EXPECT_ENV", "GROUP", "build", "compiled_modules"]

# The per-period path of a closed-loop run (bench/closed_loop_speed.py): the TCU, the lock-step bus ends, the plant's
# I/O, the run's summary, as paths from the project's root (setup.py takes this tuple as it stands, with ast). Not a
# module with a class derived from a third-party one (protocol/local.py's can.BusABC): with the third-party types
# unknown to mypy, mypyc would make it a native class, which the base cannot initialise.
COMPILED = (
    "ecu_stub/calibration.py", "ecu_stub/clutch_model.py", "ecu_stub/controller.py", "ecu_stub/monitor.py",
    "ecu_stub/pid.py", "ecu_stub/plausibility.py", "ecu_stub/runner.py", "ecu_stub/sensor_checks.py",
    "dsg_hil/protocol/lockstep.py", "dsg_hil/protocol/plan.py", "dsg_hil/protocol/validity.py",
    "dsg_hil/results/summary.py", "dsg_hil/sim/plant_io.py", "dsg_hil/sim/runner.py",
)
GROUP = "dsg_hil_compiled"  # mypyc's group: the compiled modules' machine code is one library, GROUP + "__mypyc"
EXPECT_ENV = "DSG_HIL_EXPECT_COMPILED"  # set (not "" or "0"): the tests fail unless every module runs compiled


def compiled_modules() -> dict[str, bool]:
    """Each module of :data:`COMPILED` (by its import name, imported here): True where it was loaded from an
    extension module, False where from its source."""
    loaded = {}
    for path in COMPILED:
        name = path.removesuffix(".py").replace("/", ".")
        loaded[name] = (importlib.import_module(name).__file__ or "").endswith(tuple(EXTENSION_SUFFIXES))
    return loaded


def build() -> str:
    """``compiled`` (every module of :data:`COMPILED` an extension module), ``pure`` (none) or ``mixed`` (a broken
    install: the compiled modules share one library)."""
    states = set(compiled_modules().values())
    return "mixed" if len(states) > 1 else "compiled" if states == {True} else "pure"
