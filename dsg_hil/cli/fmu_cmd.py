"""``dsg-hil fmu export``: the plant (or ecu-stub's controller) as an FMI 2.0 co-simulation FMU (extra ``fmi``)."""

from __future__ import annotations

import argparse

from . import command_help
from .common import progress

__all__ = ["add_subparser"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "fmu", help=command_help("fmu"),
        description="Write the plant as an FMI 2.0 co-simulation FMU (PythonFMU): inputs the TCU's commands and the "
                    "driver's, outputs every plant signal of the DBC (and the simulation-only truth) under its DBC "
                    "name and unit, parameters the parameter file's values. The FMU runs dsg_hil from the host's "
                    "Python: install dsg-hil[fmi] where it is imported. Needs the fmi extra.")
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    export = actions.add_parser("export", help="write the FMU", description="Write the FMU.")
    export.add_argument("--out", metavar="FILE", default="dsg_hil_plant.fmu",
                        help="the FMU to write (default: dsg_hil_plant.fmu)")
    export.add_argument("--params", metavar="FILE",
                        help="parameter file (TOML) layered on the shipped one, put into the FMU: its values are "
                             "the FMU parameters' start values")
    export.add_argument("--model", choices=("plant", "tcu"), default="plant",
                        help="plant (default), or tcu: ecu-stub's creep controller as a controller FMU (for "
                             "'dsg-hil run --controller')")
    parser.set_defaults(func=_do_fmu)


def _do_fmu(args: argparse.Namespace) -> int:
    from ..fmi.export import export_fmu  # noqa: PLC0415 - the package (pythonfmu: when the FMU is written)
    path = export_fmu(args.out, model=args.model, params=args.params)
    progress(f"wrote {path} ({args.model}; needs dsg_hil[fmi] in the host's Python)")
    return 0
