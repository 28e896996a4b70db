"""The 5,000-run safety sample's slowest, heaviest handovers to a cool CH (issue 18; on 7ecfd2f each left +-20 % of
the desired speed through a handover without a frame fault or the driver's pedal): their inputs as the sweep's table
holds them, for the closed-loop tests (``test_safety_scenarios``) and the benchmarks that analyse them
(``bench/handover_judder.py``, ``bench/judder_reference.py``). The generators' other settings do not act; a run is
``load_space(SAFETY_SPACE).task(0, RUNS[name])``."""

from __future__ import annotations

from typing import Any

__all__ = ["KEYS", "RUNS"]

KEYS = ("grade_rad", "engine_speed_rpm", "initial.T_clutch_c", "initial.T_oil_c", "params.vehicle.m",
        "driver.behaviour", "driver.desired_speed_mps", "driver.creep_s", "driver.stop_s", "driver.drag_level",
        "driver.drag_onset_s", "driver.drag_duration_s")
RUNS: dict[str, dict[str, Any]] = {name: dict(zip(KEYS, values)) for name, values in {
    "r00652": (0.184370789598004, 948.2784860158861, 69.80807028178678, 86.61325087837126, 8298.792725087817,
               "overheat_restart", 0.08579475690638856, 58.37174993638431, 8.340529146911479, 0.09983494458933198,
               66.16528601033124, 233.73787929912368),
    "r00857": (0.14476453132093034, 831.1312202491097, 95.54113910389941, 56.21144806759565, 8341.197503748841,
               "overheat_restart", 0.05339452584310453, 35.17404027248082, 11.97928176521196, 0.03878309450312592,
               36.47450371762947, 178.33588605025523),
    "r01753": (0.22713559771481176, 825.8118937532072, 121.31496154742162, 54.439970156702046, 6182.865214748008,
               "brake_drag", 0.053145153336646905, 40.65932131583172, 17.654316736945255, 0.08338826203244894,
               228.12203979546445, 126.19142269806377),
    "r03843": (0.19718890915232415, 1045.365768019011, 63.089843292809086, 94.77018155627229, 7952.77219125052,
               "brake_drag", 0.06143896692737886, 10.970762834732344, 10.57015483815429, 0.013560103985758597,
               183.0583866295659, 142.5542950921455),
    "r04681": (0.19103900803285326, 988.0833050213257, 78.6484617160881, 91.41456730677356, 9714.861878936683,
               "brake_drag", 0.050838824794822705, 16.742545998589982, 12.880153124038511, 0.01192565338293773,
               141.65365863972733, 129.77246878922898),
}.items()}
