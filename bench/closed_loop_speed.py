"""Lock-step closed loop (plant + ecu-stub TCU) on python-can's virtual interface, in one process:
simulated seconds per wall second, and the plant alone for comparison, measured in this one run.

    python bench/closed_loop_speed.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import time

import can

from dsg_hil.physics.params import load_params
from dsg_hil.physics.thermal import NODES
from dsg_hil.plant import Plant, PlantInputs
from dsg_hil.plant_io import PLANT_USES
from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.runner import PlantRunner
from dsg_hil.scenario import load_scenario
from ecu_stub.runner import TCU_USES, TcuRunner


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated duration (default 60)")
    args = ap.parse_args()
    params, db = load_params(), load_dbc()
    scenario = load_scenario().with_duration(args.seconds)
    T_init = {n: scenario.T_oil_c for n in NODES} | {"CL": scenario.T_clutch_c, "CH": scenario.T_clutch_c}

    plant_bus, tcu_bus = (can.Bus(interface="virtual", channel="bench") for _ in range(2))
    runner = PlantRunner(Plant(params, T_init=T_init), scenario, Codec(db, PLANT_USES), plant_bus)
    tcu = TcuRunner(Codec(db, TCU_USES), tcu_bus)
    t0 = time.perf_counter()
    runner.run_lockstep(pump=tcu.pump)
    wall_loop = time.perf_counter() - t0
    frames = runner.frames()
    plant_bus.shutdown()
    tcu_bus.shutdown()

    plant = Plant(params, T_init=T_init)
    inputs = PlantInputs(P_CL_cmd=0.5e6, brake=0.0)
    t0 = time.perf_counter()
    for _ in range(int(round(args.seconds / plant.dt))):
        plant.step(inputs)
    wall_plant = time.perf_counter() - t0

    print(f"lock-step closed loop on virtual, {args.seconds:g} simulated s, 1 ms plant step, 10 ms control period")
    print(f"{'':<34}{'sim s / wall s':>15}{'wall s':>9}")
    print(f"{'closed loop (plant + TCU + CAN)':<34}{args.seconds / wall_loop:>15.1f}{wall_loop:>9.2f}"
          f"   frames sent {frames['sent']}, received {frames['received']}")
    print(f"{'plant alone':<34}{args.seconds / wall_plant:>15.1f}{wall_plant:>9.2f}")
    print(f"ratio closed loop / plant alone: {wall_plant / wall_loop:.2f}")


if __name__ == "__main__":
    main()
