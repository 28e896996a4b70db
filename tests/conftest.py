from __future__ import annotations

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
    config.addinivalue_line("markers", "slow: a minute or so: the 100-s cases against solve_ivp; building a wheel "
                                       "(needs the package index for setuptools)")
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


@pytest.hookimpl(trylast=True)  # after dsg_hil/e2e/conftest.py has marked its tests
def pytest_collection_modifyitems(config, items):
    """Deselect the vcan tests (not skip: they never count as run) unless asked for: ``DSG_HIL_REQUIRE_VCAN``
    set (``dsg-hil vcan`` sets it) or a ``-m`` expression that names ``vcan``. Any other ``-m`` (``"not slow"``)
    leaves them out too, so a marker expression cannot bring them back by replacing a configured one."""
    if os.environ.get(ENV_REQUIRE) or re.search(r"\bvcan\b", config.option.markexpr or ""):
        return
    vcan = [item for item in items if item.get_closest_marker("vcan")]
    if vcan:
        config.hook.pytest_deselected(items=vcan)
        items[:] = [item for item in items if not item.get_closest_marker("vcan")]
