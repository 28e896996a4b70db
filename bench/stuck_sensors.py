"""Stuck thermal inputs in the closed loop: a 30-s creep from CL 228 / CH 235 / oil 130 degC on Table I's
grade, one signal stuck (CRC and counter valid) from 2 s to the end; one JSON line per case with the true plates'
maxima, seconds above 250 degC, the stop reason and the TCU's implausible counts (ecu_stub/sensor_checks.py).

    python bench/stuck_sensors.py [CASE ...] [--json]     (default: all; about 1 s each)

``--json``: one JSON object, ``{"cases": [...]}``, instead of a line per case.

Cases: none, and SIGNAL=VALUE of tests/ecu_stub/test_sensor_checks.py's STUCK plus EngineSpeed=0 and =3000.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout: its tests' scenarios
sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/: _cases (also under python -P)

from _cases import parse_cases  # noqa: E402
from tests.ecu_stub.test_sensor_checks import STUCK, hot_creep  # noqa: E402

EXTRA = {"EngineSpeed=0": ("PLANT_ENGINE.EngineSpeed", 0.0), "EngineSpeed=3000": ("PLANT_ENGINE.EngineSpeed", 3000.0)}


CASES = {"none": None, **{f"{s}={v:g}": (t, v) for s, (t, v) in STUCK.items()}, **EXTRA}


def main() -> None:
    names, as_json = parse_cases(__doc__ or "", CASES)
    rows = []
    for name in names:
        summary, counts = hot_creep(stuck=CASES[name])
        rows.append({"case": name, "max_plate_temp_c": summary["max_plate_temp_c"],
                     "time_above_limit_s": summary["time_above_limit_s"], "stop_reason": summary["stop_reason"],
                     "implausible": {k: n for k, n in counts["implausible"].items() if n}})
        if not as_json:
            print(json.dumps(rows[-1]), flush=True)
    if as_json:
        print(json.dumps({"cases": rows}))


if __name__ == "__main__":
    main()
