from __future__ import annotations

import logging
import os
import re

import pytest

from dsg_hil.physics.params import load_params
from dsg_hil.e2e.vcan import ENV_REQUIRE

# The tests test the installed package (a regular install: the compiled build), never the checkout they come from:
# pytest imports them with --import-mode=importlib (pyproject.toml), which puts no directory on sys.path, and the
# Python processes they start (from the checkout, some of them) do not put their working directory or script's
# directory first either. tests/test_packaging.py checks both.
os.environ.setdefault("PYTHONSAFEPATH", "1")


def pytest_configure(config):
    register_plugin(config)
    config.addinivalue_line("markers", "slow: over about 1.5 s on a 2-core machine (closed loops, sweeps, processes, "
                                       "the 100-s cases against solve_ivp, building a wheel): the compiled build's "
                                       "run has them, the Contributing run (-m 'not slow or wheel') leaves them out")
    config.addinivalue_line("markers", "wheel: builds a wheel of the checkout (pip, mypyc) and tests it; run where "
                                       "dsg-hil is installed editable from the checkout (the contributors' run): a "
                                       "regular install's run tests that install itself, and leaves them out "
                                       "unless -m names wheel")
    config.addinivalue_line("markers", "vcan: end-to-end on a real SocketCAN vcan0 with separate processes (run "
                                       "with 'dsg-hil vcan'); deselected unless DSG_HIL_REQUIRE_VCAN is set or -m "
                                       "names vcan")


def register_plugin(config) -> None:
    """The dsg_hil plugin (fixture dsg_hil_run) comes by its pytest11 entry point once dsg-hil is installed; from
    a checkout on PYTHONPATH register it here, unless disabled (``-p no:dsg_hil``)."""
    manager = config.pluginmanager
    if not manager.has_plugin("dsg_hil") and not manager.is_blocked("dsg_hil"):
        from dsg_hil.testing import plugin as pytest_plugin

        manager.register(pytest_plugin, "dsg_hil")


@pytest.fixture(scope="session")
def params():
    return load_params()


@pytest.fixture(autouse=True)
def fresh_process_logging():
    """Each test starts and ends with the logging a fresh process has: a command run in the test's process
    (``main([..., "-q"])``, in a test or a module's fixture) sets the ``dsg_hil``/``ecu_stub`` loggers' level, the
    tester libraries' and the quiet flag of the progress lines for good (busopts.setup_logging, diag_cmd._log_uds),
    and a later test in that process would not see the warnings it checks. Which tests ran before in one process is
    pytest-xdist's to decide (dsg_hil.sim.runner's 'TCU_CMD missing' warning went missing after
    tests/cli/test_diag_cmd.py's 'dsg-hil plant -q' on the same worker)."""
    _fresh_logging()
    yield
    _fresh_logging()


def _fresh_logging() -> None:
    from dsg_hil.cli.common import set_quiet  # noqa: PLC0415
    from dsg_hil.cli.diag_cmd import UDS_LOGGERS  # noqa: PLC0415

    for name in ("dsg_hil", "ecu_stub", *UDS_LOGGERS):  # NOTSET in a fresh process (none is set on import)
        logging.getLogger(name).setLevel(logging.NOTSET)
    set_quiet(False)


@pytest.hookimpl(trylast=True)  # after dsg_hil/e2e/conftest.py has marked its tests
def pytest_collection_modifyitems(config, items):
    """Deselect the vcan tests (not skip: they never count as run) unless asked for: ``DSG_HIL_REQUIRE_VCAN``
    set (``dsg-hil vcan`` sets it) or a ``-m`` expression that names ``vcan``. Any other ``-m`` (``"not slow"``)
    leaves them out too, so a marker expression cannot bring them back by replacing a configured one. The wheel
    tests likewise, on a regular install (they build the checkout's wheel: the contributors' editable run has
    them, so CI runs them once, not in both of its runs)."""
    markexpr = config.option.markexpr or ""
    left_out = set()
    if not (os.environ.get(ENV_REQUIRE) or re.search(r"\bvcan\b", markexpr)):
        left_out.add("vcan")
    if not (editable_install() or re.search(r"\bwheel\b", markexpr)):
        left_out.add("wheel")  # the wheel tests: in the editable run (CI runs both), not twice
    out = [item for item in items if any(item.get_closest_marker(name) for name in left_out)]
    if out:
        config.hook.pytest_deselected(items=out)
        items[:] = [item for item in items if item not in out]


def editable_install() -> bool:
    """Whether the dsg-hil installed is an editable install (pip's direct_url.json, PEP 610); no distribution (the
    checkout on PYTHONPATH) counts as one."""
    import json  # noqa: PLC0415
    from importlib import metadata  # noqa: PLC0415

    try:
        direct = json.loads(metadata.distribution("dsg-hil").read_text("direct_url.json") or "{}")
    except metadata.PackageNotFoundError:
        return True
    return bool(direct.get("dir_info", {}).get("editable", False))
