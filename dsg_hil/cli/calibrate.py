"""``dsg-hil calibrate``: re-run the calibrations and compare them with the parameter file."""

from __future__ import annotations

import argparse

from ..calibration import calibrate_h_plate_oil, calibrate_stribeck, rise_residuals, with_h_plate_oil
from .common import add_params_option, params_from, progress


def add_subparser(sub) -> None:
    parser = sub.add_parser(
        "calibrate", help="re-run the calibrations of the 'calibrated' parameters",
        description="Re-run every calibration behind a parameter tagged 'calibrated' (friction.A_stribeck against "
                    "Section V.B's mu_CH; thermal.clutch.h_plate_oil against the four Section III.C rises) and "
                    "print the fitted values beside the parameter file's. Takes about a minute.")
    add_params_option(parser)
    parser.set_defaults(func=_do_calibrate)


def _do_calibrate(args: argparse.Namespace) -> int:
    params = params_from(args)
    progress("fitting friction.A_stribeck ...")
    fit = calibrate_stribeck(params)
    print(f"friction.A_stribeck          fitted {fit.A_stribeck:.5f}  file {params.friction.A_stribeck:.5f}"
          f"  (CH slip {fit.slip_rpm:.1f} r/min, mu {fit.mu_start:.4f} -> {fit.mu_end:.4f})")
    progress("fitting thermal.clutch.h_plate_oil (four 100-s rig runs per evaluation) ...")
    h = calibrate_h_plate_oil(params)
    residuals = rise_residuals(with_h_plate_oil(params, h))
    print(f"thermal.clutch.h_plate_oil   fitted {h:.1f}  file {params.thermal.clutch.h_plate_oil:.1f}"
          f"  (rise residuals {', '.join(f'{r:+.2f}' for r in residuals)} K)")
    return 0
