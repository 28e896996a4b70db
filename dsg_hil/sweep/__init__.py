"""``dsg-hil sweep``: many runs of a space of scenarios, parameters, driver behaviours and faults on Dask
distributed, judged on the plant's truth; or (``--search``) an optimiser hunting for a violation.

One entry point, :func:`run_sweep` (and :func:`run_search`), built on :func:`dsg_hil.sim.run.open_run`::

    space.py       the space file (TOML): distributions, sampler, controller, limits    drivers.py  [[driver]] events
    controllers.py the controller under test   worker.py  one run (plain data in and out)   verdict.py  the judgement
    engine.py      Dask: LocalCluster or --scheduler, as_completed, retries               results.py  Parquet + JSON
    page.py        sweep.md, figures, the reproducing commands                             search.py   Optuna
    code.py        which code made the runs (a digest per row and in sweep.json)
    latent.py      latent sensor faults: offsets and gains on the TCU's inputs, sized by its checks' thresholds

The names are imported when first used (PEP 562): importing this package loads neither Dask nor the plant.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..common.lazy import lazy_names

if TYPE_CHECKING:
    from .engine import SweepResult, run_sweep
    from .page import write_page
    from .search import run_search
    from .space import Space, SpaceError, load_space

_WHERE = {"Space": "space", "SpaceError": "space", "SweepResult": "engine", "load_space": "space",
          "run_search": "search", "run_sweep": "engine", "write_page": "page"}

__all__ = ["Space", "SpaceError", "SweepResult", "load_space", "run_search", "run_sweep", "write_page"]

__getattr__ = lazy_names(__name__, _WHERE, globals())
