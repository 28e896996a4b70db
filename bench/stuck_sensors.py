"""Issue 18's stuck thermal inputs in the closed loop: a 30-s creep from CL 228 / CH 235 / oil 130 degC on Table I's
grade, one signal stuck (CRC and counter valid) from 2 s to the end; one JSON line per case with the true plates'
maxima, seconds above 250 degC, the stop reason and the TCU's implausible counts (ecu_stub/sensor_checks.py).

    PYTHONPATH=. python bench/stuck_sensors.py [CASE ...]      (default: all; about 1 s each)

Cases: none, and SIGNAL=VALUE of tests/ecu_stub/test_sensor_checks.py's STUCK plus EngineSpeed=0 and =3000.
"""

from __future__ import annotations

import json
import sys

from tests.ecu_stub.test_sensor_checks import STUCK, hot_creep

EXTRA = {"EngineSpeed=0": ("PLANT_ENGINE.EngineSpeed", 0.0), "EngineSpeed=3000": ("PLANT_ENGINE.EngineSpeed", 3000.0)}


def main(names: list[str]) -> None:
    cases = {"none": None, **{f"{s}={v:g}": (t, v) for s, (t, v) in STUCK.items()}, **EXTRA}
    for name in names or list(cases):
        summary, counts = hot_creep(stuck=cases[name])
        print(json.dumps({"case": name, "max_plate_temp_c": summary["max_plate_temp_c"],
                          "time_above_limit_s": summary["time_above_limit_s"], "stop_reason": summary["stop_reason"],
                          "implausible": {k: n for k, n in counts["implausible"].items() if n}}), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
