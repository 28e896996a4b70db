"""pytest plugin ``dsg_hil`` (entry point ``pytest11``): the fixture ``dsg_hil_run`` runs the plant in lockstep
against your controller. Disable it with ``pytest -p no:dsg_hil``.

Importing this module imports nothing but pytest: the plant, numpy and python-can are loaded when a test first
calls the fixture, so the plugin costs other test runs nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from . import PlantRun

__all__ = ["dsg_hil_run"]


@pytest.fixture(scope="session")
def dsg_hil_run(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., PlantRun]:
    """Run the plant in lockstep against a controller: ``dsg_hil_run(controller=None, *, scenario=None,
    duration=None, params=None, faults=None, fault_seed=0, log="run.asc", out_dir=None, dbc=None, binding=None)``
    returns a :class:`dsg_hil.testing.PlantRun` (``summary``, ``signals``, ``truth``, ``frames``, ``log``).

    ``controller``: ``None`` the bundled ecu-stub in process; a command line (list of str, ``"{bus_args}"`` for
    the bus options) started as a process on a udp_multicast group of the run's own; or an object with
    ``step(t, inputs)`` (:class:`dsg_hil.testing.Controller`). Each run writes into a directory of its own under
    pytest's temporary directory (or ``out_dir``). Session-scoped, so module-scoped fixtures can share a run.
    See :func:`dsg_hil.testing.run_plant` for every argument."""
    def run(controller: Any = None, *, out_dir: str | Path | None = None, **kwargs: Any) -> PlantRun:
        from . import run_plant

        directory = out_dir if out_dir is not None else tmp_path_factory.mktemp("dsg_hil_run")
        return run_plant(controller, out_dir=directory, **kwargs)

    return run
