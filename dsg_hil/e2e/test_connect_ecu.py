"""docs/tutorials/connect-ecu.md on vcan0: ecu-stub on the ARXML example's pair in the ECU's place, the plant on the
same pair in real time, as the page's two lines start them (with the suite's --duration): every frame the plant
reads accepted under the ARXML's E2E profiles, the TCU's commands and states heard."""

from __future__ import annotations

import json
import shlex
import subprocess
from importlib import resources
from pathlib import Path

from .conftest import STARTUP, TCU_IDLE_EXIT, console

EXAMPLE = Path(str(resources.files("dsg_hil") / "data" / "examples" / "arxml"))
PAGE_DBC = "dbc/examples/arxml/tcu.arxml"
# the page's lines (tests/docs/test_inventory.py names this test for them)
ECU_LINE = "ecu-stub -i socketcan -c vcan0 --dbc dbc/examples/arxml/tcu.arxml --binding my_ecu.binding.toml"
PLANT_LINE = ("dsg-hil plant -i socketcan -c vcan0 --dbc dbc/examples/arxml/tcu.arxml --binding my_ecu.binding.toml "
              "--duration 20 --summary summary.json")


def _words(line: str, tmp_path: Path, duration: float) -> list[str]:
    words = [str(EXAMPLE / "tcu.arxml") if w == PAGE_DBC else w for w in shlex.split(line)]
    words[0] = console(words[0])
    if "--duration" in words:
        words[words.index("--duration") + 1] = str(duration)
    return words


def test_the_ecu_tutorial_s_pair_on_vcan0_in_real_time(tmp_path, duration):
    (tmp_path / "my_ecu.binding.toml").write_bytes((EXAMPLE / "tcu.binding.toml").read_bytes())
    tcu = subprocess.Popen([*_words(ECU_LINE, tmp_path, duration), "--idle-exit", TCU_IDLE_EXIT], cwd=tmp_path,
                           stderr=subprocess.PIPE, text=True)
    try:
        plant = subprocess.run(_words(PLANT_LINE, tmp_path, duration), cwd=tmp_path, capture_output=True, text=True,
                               timeout=STARTUP + 60 * duration)
        assert plant.returncode == 0, plant.stderr[-2000:]
        tcu_err = tcu.communicate(timeout=120)[1]
        assert tcu.returncode == 0, tcu_err[-2000:]
    finally:
        if tcu.poll() is None:
            tcu.kill()
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    frames = summary["frames"]
    assert summary["mode"] == "realtime" and frames["rejected"] == 0
    assert frames["by_message"]["TCU_CMD"]["taken"] > 0 and frames["by_message"]["TCU_STATUS"]["taken"] > 0
