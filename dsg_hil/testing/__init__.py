"""Test a controller against the plant: :func:`run_plant` (in :mod:`.harness`) runs a scenario in lockstep against
ecu-stub, a controller process or a Python object, and gives the summary, the decoded signals, the plant's truth and
the log; :mod:`.plugin` is the pytest plugin (fixture ``dsg_hil_run``).

The names are imported when first used (PEP 562): loading the pytest plugin loads none of numpy and python-can.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..common.lazy import lazy_names

if TYPE_CHECKING:
    from .controllers import Controller, ControllerProcess
    from .harness import PlantRun, run_plant
    from .signals import Signals

_WHERE = {"Controller": "controllers", "ControllerProcess": "controllers", "PlantRun": "harness",
          "run_plant": "harness", "Signals": "signals"}

__all__ = ["Controller", "ControllerProcess", "PlantRun", "Signals", "run_plant"]

__getattr__ = lazy_names(__name__, _WHERE, globals())
