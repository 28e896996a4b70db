"""dsg-hil: a CAN-bus hardware-in-the-loop plant of a DSG (dual wet clutch) creeping in traffic.

The layout follows the data flow, one direction (``tests/test_layout.py`` holds the table of allowed imports)::

    common/    errors and exit codes, files, units, lazy names   (shared with ecu-stub)
    protocol/  the CAN contract: DBC codec, counters and CRC, validity, buses, faults
    physics/   the model: pure functions, the plant, the rig     (no clock, no bus, no files)
    results/   metrics and the run summary, from a trace or a decoded log
    sim/       scenario, the plant's CAN edge, the runner, the closed loop, open_run
    paper/     reference numbers, validation, calibration, reduced model, report and figures
    testing/   run_plant and the pytest plugin          cli/  the dsg-hil command
    sweep/     dsg-hil sweep: many runs on Dask, judged on the plant's truth; --search (Optuna)
    fmi/       the plant as an FMU, a controller FMU as the TCU (extra fmi; imported by cli only)
    e2e/       the vcan end-to-end suite and 'dsg-hil vcan'  data/ the shipped DBC, parameters, scenario

The names below are imported when first used (PEP 562): ``import dsg_hil`` loads no numpy, cantools or python-can.
A run is scripted with ``dsg_hil.open_run(dsg_hil.RunConfig(...))`` (see :mod:`dsg_hil.sim.run`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .common.lazy import lazy_names
from .common.moved import install as _install_moved

__version__ = "0.1.0"

if TYPE_CHECKING:
    from .common.errors import DsgHilError, InputError, ResultError, RunError
    from .physics.params import Params, load_params
    from .physics.plant import Plant
    from .protocol import load_dbc
    from .results.outcome import Summary
    from .sim.loop import run_closed_loop
    from .sim.run import Run, RunConfig, open_run
    from .sim.scenario import Scenario, load_scenario
    from .testing import run_plant

_WHERE = {"DsgHilError": "common.errors", "InputError": "common.errors", "ResultError": "common.errors",
          "RunError": "common.errors", "Params": "physics.params", "load_params": "physics.params",
          "Plant": "physics.plant", "load_dbc": "protocol", "Scenario": "sim.scenario",
          "load_scenario": "sim.scenario", "run_plant": "testing", "Summary": "results.outcome",
          "run_closed_loop": "sim.loop", "Run": "sim.run", "RunConfig": "sim.run", "open_run": "sim.run"}

__all__ = ["DsgHilError", "InputError", "Params", "Plant", "ResultError", "Run", "RunConfig", "RunError", "Scenario",
           "Summary", "__version__", "load_dbc", "load_params", "load_scenario", "open_run", "run_closed_loop",
           "run_plant"]

__getattr__ = lazy_names(__name__, _WHERE, globals())
_install_moved()
