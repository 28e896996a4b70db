"""Import paths of modules that moved in 0.2 (the layout by data flow), kept importable for one release.

``import dsg_hil.runner`` gives the very module object of ``dsg_hil.sim.runner`` (so a patch applied through the
old path patches the new one) and warns once with a :class:`DeprecationWarning` naming the new path. The finder is
installed by ``dsg_hil/__init__.py``, first on ``sys.meta_path``: it answers only for the names in :data:`MOVED` (no
file is left at those paths), before the path finder could load a moved package's module under its old name twice.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from collections.abc import Sequence
from types import ModuleType

__all__ = ["MOVED", "install"]

MOVED = {  # old import path: new import path (0.1 -> 0.2)
    "dsg_hil.errors": "dsg_hil.common.errors",
    "dsg_hil.faults": "dsg_hil.protocol.faults",
    "dsg_hil.protocol.errors": "dsg_hil.common.errors",
    "dsg_hil.protocol.lazy": "dsg_hil.common.lazy",
    "dsg_hil.plant": "dsg_hil.physics.plant",
    "dsg_hil.rig": "dsg_hil.physics.rig",
    "dsg_hil.continuous": "dsg_hil.physics.continuous",
    "dsg_hil.scenario": "dsg_hil.sim.scenario",
    "dsg_hil.plant_io": "dsg_hil.sim.plant_io",
    "dsg_hil.runner": "dsg_hil.sim.runner",
    "dsg_hil.loop": "dsg_hil.sim.loop",
    "dsg_hil.summary": "dsg_hil.results.summary",
    "dsg_hil.creep_rows": "dsg_hil.results.creep_rows",
    "dsg_hil.reference": "dsg_hil.paper.reference",
    "dsg_hil.validation": "dsg_hil.paper.validation",
    "dsg_hil.calibration": "dsg_hil.paper.calibration",
    "dsg_hil.creep_model": "dsg_hil.paper.creep_model",
    "dsg_hil.plots": "dsg_hil.paper.plots",
    "dsg_hil.report": "dsg_hil.paper.report",
    "dsg_hil.report.figures": "dsg_hil.paper.report.figures",
    "dsg_hil.report.log": "dsg_hil.paper.report.log",
    "dsg_hil.report.page": "dsg_hil.paper.report.page",
    "dsg_hil.report.paper": "dsg_hil.paper.report.paper",
    "dsg_hil.pytest_plugin": "dsg_hil.testing.plugin",
    "dsg_hil.vcan": "dsg_hil.e2e.vcan",
}


class _Alias(importlib.abc.Loader):
    def __init__(self, new: str) -> None:
        self.new = new

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        warnings.warn(f"{spec.name} moved to {self.new}; the old path goes in the next release",
                      DeprecationWarning, stacklevel=2)
        return importlib.import_module(self.new)

    def exec_module(self, module: ModuleType) -> None:
        """The module is the new one, already executed."""


class MovedFinder(importlib.abc.MetaPathFinder):
    """Finds the old paths of :data:`MOVED`."""

    def find_spec(self, fullname: str, path: Sequence[str] | None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        new = MOVED.get(fullname)
        if new is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, _Alias(new), is_package=False)


def install() -> None:
    """Put the finder first on ``sys.meta_path`` (once)."""
    if not any(isinstance(finder, MovedFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, MovedFinder())
