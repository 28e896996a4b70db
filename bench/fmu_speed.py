"""The plant FMU under FMPy against the in-process plant, side by side in one run (simulated seconds per wall
second; no timing is asserted anywhere).

    python bench/fmu_speed.py [--seconds 60] [--json]

Both take the same inputs (CL commanded to 0.6 MPa, brake released: the vehicle creeps, CL slips and heats) in
10-ms communication steps of 10 plant steps: ``in_process`` calls :meth:`Plant.advance` and reads the outputs;
``fmu`` is ``dsg-hil fmu export``'s FMU stepped through FMPy's FMU2Slave (setReal, doStep, getReal of all 24
outputs per step), in this process (its Python runs dsg_hil, as a tool-coupling FMU does). The difference is the
price of the FMI layer (ctypes, PythonFMU's C++ and its Python facade). ``identical`` says whether the two
trajectories' final outputs agree bit for bit.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

from dsg_hil.common.units import CV
from dsg_hil.fmi.cosim import open_fmu
from dsg_hil.fmi.export import export_fmu
from dsg_hil.fmi.signals import PLANT_OUTPUTS
from dsg_hil.physics.params import load_params
from dsg_hil.physics.plant import PlantInputs
from dsg_hil.sim.plant_io import plant_signals
from dsg_hil.sim.run import plant_for
from dsg_hil.sim.scenario import DriverInput, load_scenario

PERIOD, P_CL_MPA = 0.01, 0.6


def in_process(seconds: float) -> tuple[float, list[float]]:
    """Simulated s per wall s of the plant in this process, and its final outputs in DBC units."""
    plant = plant_for(load_scenario(), load_params())
    inputs = PlantInputs(P_CL_cmd=P_CL_MPA * CV.MPA_TO_PA)
    plant.advance(inputs, 10)  # compiled code loaded before the clock starts
    plant = plant_for(load_scenario(), load_params())
    t0 = time.perf_counter()
    for _ in range(round(seconds / PERIOD)):
        out = plant.advance(inputs, 10)
        values = plant_signals(out, DriverInput(out.t, False, 0.0, 0.0))  # the outputs, as the FMU gives them
    wall = time.perf_counter() - t0
    return seconds / wall, [values[s.message][s.signal] for s in PLANT_OUTPUTS]


def fmu(path: Path, seconds: float) -> tuple[float, list[float]]:
    """Simulated s per wall s of the plant FMU stepped through FMPy, and its final outputs."""
    instance, refs = open_fmu(path, "plant")
    outputs = [refs[s.name][1] for s in PLANT_OUTPUTS]  # (type, value reference): the outputs are Reals
    P_CL = [refs["P_CL_Cmd"][1]]
    t0 = time.perf_counter()
    for k in range(round(seconds / PERIOD)):
        instance.setReal(P_CL, [P_CL_MPA])
        instance.doStep(currentCommunicationPoint=k * PERIOD, communicationStepSize=PERIOD)
        values = instance.getReal(outputs)
    wall = time.perf_counter() - t0
    return seconds / wall, values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per case (default 60)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = export_fmu(Path(tmp) / "dsg_hil_plant.fmu")
        native, native_out = in_process(args.seconds)
        through_fmi, fmu_out = fmu(path, args.seconds)
    figures = {"seconds": args.seconds, "in_process_sim_s_per_wall_s": round(native, 1),
               "fmu_fmpy_sim_s_per_wall_s": round(through_fmi, 1), "ratio": round(native / through_fmi, 2),
               "identical": native_out == fmu_out}
    if args.json:
        print(json.dumps(figures))
    else:
        print(f"plant, {args.seconds:g} simulated s in 10-ms steps:  in process {native:8.1f} sim s / wall s"
              f"   FMU through FMPy {through_fmi:8.1f} sim s / wall s   (x{native / through_fmi:.1f})"
              f"   final outputs identical: {figures['identical']}")
    sys.stdout.flush()
    os._exit(0)  # one FMU instance freed by nobody: skip the interpreter's clean-up (PythonFMU, see tests/fmi)


if __name__ == "__main__":
    main()
