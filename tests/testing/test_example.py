"""The pytest tutorial's plugin example, run as a user would: the block itself, in a pytest of its own (a fresh
process), against ecu-stub started as a controller process on udp_multicast."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parents[2] / "docs" / "tutorials" / "pytest.md"
# a checkout on PYTHONPATH has no entry point: register the plugin as tests/conftest.py does
CONFTEST = '''
def pytest_configure(config):
    manager = config.pluginmanager
    if not manager.has_plugin("dsg_hil") and not manager.is_blocked("dsg_hil"):
        from dsg_hil.testing import plugin as pytest_plugin

        manager.register(pytest_plugin, "dsg_hil")
'''


def readme_example() -> str:
    block = re.search(r"```python\n(.*?)```", PAGE.read_text(encoding="utf-8"), re.S)
    assert block, "docs/tutorials/pytest.md: no python block"
    return block.group(1)


def run_pytest(directory: Path, *options: str) -> subprocess.CompletedProcess[str]:
    (directory / "conftest.py").write_text(CONFTEST, encoding="utf-8")
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *options, str(directory)],
                          cwd=directory, capture_output=True, text=True, timeout=900)


@pytest.mark.slow
def test_the_readme_example_passes(tmp_path):
    (tmp_path / "test_my_ecu.py").write_text(readme_example(), encoding="utf-8")
    proc = run_pytest(tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout


def test_p_no_dsg_hil_disables_the_plugin(tmp_path):
    (tmp_path / "test_uses_it.py").write_text("def test_x(dsg_hil_run):\n    pass\n", encoding="utf-8")
    proc = run_pytest(tmp_path, "-p", "no:dsg_hil")
    assert proc.returncode == 1 and "fixture 'dsg_hil_run' not found" in proc.stdout, proc.stdout + proc.stderr
