"""The FMI guide's FMPy snippet runs as printed (in a directory and a process of its own: it instantiates the FMU)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parents[2] / "docs" / "how-to" / "fmi.md"


def fmpy_snippet() -> str:
    """The FMI guide's python block that calls simulate_fmu."""
    section = PAGE.read_text(encoding="utf-8")
    blocks = [block.split("```", 1)[0] for block in section.split("```python\n")[1:]]
    return next(block for block in blocks if "simulate_fmu(" in block)


@pytest.mark.slow
def test_the_guide_s_fmpy_snippet_runs(tmp_path):
    import os

    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    done = subprocess.run([sys.executable, "-c", fmpy_snippet()], cwd=tmp_path, capture_output=True, text=True,
                          timeout=300, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    last = {name: float(value) for name, value in (line.split() for line in done.stdout.strip().splitlines()[-4:])}
    assert last["time"] == 5.0 and abs(last["P_CL"] - 0.6) < 0.01  # the script reached the plant
    assert last["SIM_TRUTH_CL.T_Plate"] > 100.0 and last["VehicleSpeed"] > 0.0
    assert (tmp_path / "dsg_hil_plant.fmu").is_file()
