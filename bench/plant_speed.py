"""Plant speed: simulated seconds per wall second at the fixed 1 ms step, against the same equations through
scipy's solve_ivp at (at least) equal accuracy, both on the same 100-s case and measured in this one run.

    python bench/plant_speed.py [--seconds 100]

The case (tests/test_continuous_reference.py): level road, engine governed at 2000 r/min, vehicle rolling,
CH pressure rising to 0.4 MPa, CH slipping throughout. "Equal accuracy": solve_ivp's tolerance is loosened
until its plate temperature and speeds are no closer to a tight reference (rtol 1e-10) than the plant's are.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import solve_ivp

from dsg_hil.continuous import pack, rhs
from dsg_hil.physics.friction import RAD_S_TO_RPM
from dsg_hil.physics.params import load_params
from dsg_hil.physics.powertrain import N_DOF, N_STATE
from dsg_hil.physics.thermal import NODES
from dsg_hil.plant import Plant, PlantInputs

I_TCL = N_STATE + NODES.index("CH")


def errors(speeds, T_CL, ref):
    """(max |plate temperature error| [K], max relative speed error) against the reference solution."""
    ref_speeds, ref_T = ref[:N_DOF].T, ref[I_TCL]
    scale = np.maximum(np.abs(ref_speeds), 1.0)
    return float(np.abs(T_CL - ref_T).max()), float((np.abs(speeds - ref_speeds) / scale).max())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=100.0, help="simulated duration (default 100)")
    args = ap.parse_args()
    params = load_params()
    inputs = PlantInputs(P_CH_cmd=0.4e6, grade=0.0, brake=0.0, engine_speed_request=2000.0 / RAD_S_TO_RPM)
    plant = Plant(params, T_init=40.0, v_init=0.5)
    y0, f = pack(plant), rhs(plant, inputs)
    n = int(round(args.seconds / plant.dt))
    every = int(round(1.0 / plant.dt))
    t_eval = np.arange(1, int(args.seconds) + 1, dtype=float)

    t0 = time.perf_counter()
    speeds, T_CL = [], []
    for k in range(1, n + 1):
        out = plant.step(inputs)
        if k % every == 0:
            speeds.append(plant.state.x[:N_DOF].copy())
            T_CL.append(out.T_CH)
    wall_plant = time.perf_counter() - t0
    speeds_a, T_CH = np.array(speeds), np.array(T_CL)  # the CH plate (I_TCL), as printed

    ref = solve_ivp(f, (0.0, t_eval[-1] + 1e-9), y0, method="Radau", rtol=1e-10, atol=1e-10, t_eval=t_eval).y
    err_plant = errors(speeds_a, T_CH, ref)

    chosen = None
    for rtol in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9):
        t0 = time.perf_counter()
        sol = solve_ivp(f, (0.0, t_eval[-1] + 1e-9), y0, method="Radau", rtol=rtol, atol=rtol, t_eval=t_eval)
        wall = time.perf_counter() - t0
        err = errors(sol.y[:N_DOF].T, sol.y[I_TCL], ref)
        if err[0] <= err_plant[0] and err[1] <= err_plant[1]:
            chosen = (rtol, wall, err, sol.nfev)
            break
    print(f"case: {args.seconds:g} s, CH slipping, 1 ms plant step; reference solve_ivp Radau rtol=1e-10")
    print(f"{'':<28}{'sim s / wall s':>15}{'wall s':>9}{'max dT_CH K':>13}{'max speed err':>15}")
    print(f"{'plant (exact ZOH, 1 ms)':<28}{args.seconds / wall_plant:>15.1f}{wall_plant:>9.2f}"
          f"{err_plant[0]:>13.2e}{err_plant[1]:>15.2e}")
    if chosen is None:
        print("solve_ivp: no tolerance down to 1e-9 reached the plant's accuracy")
        return
    rtol, wall, err, nfev = chosen
    print(f"{f'solve_ivp Radau rtol={rtol:g}':<28}{args.seconds / wall:>15.1f}{wall:>9.2f}{err[0]:>13.2e}"
          f"{err[1]:>15.2e}   ({nfev} evaluations)")
    print(f"ratio plant / solve_ivp (simulated seconds per wall second): {wall / wall_plant:.2f}")


if __name__ == "__main__":
    main()
