"""``dsg-hil calibrate``: re-run the calibrations and compare them with the parameter file."""

from __future__ import annotations

import argparse
from collections.abc import Iterable
from typing import TYPE_CHECKING

from . import command_help
from .common import add_params_option, params_from, progress

if TYPE_CHECKING:
    from ..paper.calibration import Check

__all__ = ["add_subparser"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "calibrate", help=command_help("calibrate"),
        description="Re-run every calibration behind a parameter tagged 'calibrated' (friction.A_stribeck against "
                    "Section V.B's mu_CH; thermal.clutch.test.h_plate_oil against the four Section III.C rises on "
                    "the rig; the vehicle clutches' plate capacities and cooling flows against Section V.B's "
                    "timeline with the reduced creep model on the scenario) and print the fitted values beside the "
                    "parameter file's. Takes about a minute.")
    add_params_option(parser)
    parser.add_argument("--scenario", metavar="FILE", help="creep scenario of the V.B fit (default: the shipped one)")
    parser.set_defaults(func=_do_calibrate)


def _print_checks(title: str, checks: Iterable[Check]) -> None:
    print(title)
    for c in checks:
        print(f"  {c.name:<26} {c.simulated:9.4g}  published {c.published:9.4g}  "
              f"{'ok' if c.ok else 'OUTSIDE BAND'} (+-{c.tolerance:.3g})")


def _do_calibrate(args: argparse.Namespace) -> int:
    from ..paper.calibration import (  # noqa: PLC0415 - scipy.optimize at run time only
        VEHICLE_THERMAL_KEYS,
        calibrate_h_plate_oil,
        calibrate_stribeck,
        calibrate_vehicle_thermal,
        friction_checks,
        reduced_creep,
        rise_residuals,
        timeline_checks,
        vehicle_thermal,
        with_h_plate_oil,
        with_vehicle_thermal,
    )
    from ..sim.scenario import load_scenario  # noqa: PLC0415

    params = params_from(args)
    scenario = load_scenario(args.scenario)
    progress("fitting friction.A_stribeck and the CH slip speed of Section V.B ...")
    fit = calibrate_stribeck(params)
    print(f"friction.A_stribeck          fitted {fit.A_stribeck:.5f}  file {params.friction.A_stribeck:.5f}"
          f"  (CH slip {fit.slip_rpm:.1f} r/min, mu {fit.mu_start:.4f} -> {fit.mu_end:.4f} at "
          f"P {fit.P_start_mpa:.3f} -> {fit.P_end_mpa:.3f} MPa)")
    progress("fitting thermal.clutch.test.h_plate_oil (four 100-s rig runs per evaluation) ...")
    h = calibrate_h_plate_oil(params)
    residuals = rise_residuals(with_h_plate_oil(params, h))
    print(f"thermal.clutch.test.h_plate_oil  fitted {h:.1f}  file {params.thermal.clutch.test.h_plate_oil:.1f}"
          f"  (rise residuals {', '.join(f'{r:+.2f}' for r in residuals)} K)")
    progress(f"fitting the vehicle clutches' thermal values to Section V.B's timeline ({scenario.name}) ...")
    fitted = calibrate_vehicle_thermal(params, scenario, progress=progress)
    for key, new, old in zip(VEHICLE_THERMAL_KEYS, fitted, vehicle_thermal(params)):
        print(f"{key:<32} fitted {new:.4g}  file {old:.4g}")
    result = reduced_creep(with_vehicle_thermal(params, *fitted), scenario)
    _print_checks("reduced model with the fitted values (Section V.B):",
                  timeline_checks(result) + friction_checks(result))
    return 0
