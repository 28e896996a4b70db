"""``dsg-hil validate``: the four Section III.C cases beside the paper's numbers."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..paper.reference import TOL_MU, TOL_RISE_C, TOL_TORQUE_REL
from . import command_help
from ..common.errors import ResultError
from ..common.files import check_output_path
from .common import add_params_option, params_from, positive_number, progress

__all__ = ["add_subparser"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "validate", help=command_help("validate"),
        description="Run the four Section III.C cases of the paper (clutch CL slipping 100 s at constant pressure "
                    "and relative speed from 40 degC: 0.2/0.2/0.3/0.3 MPa at 150/300/150/300 r/min) and print "
                    "them beside the published numbers. Exit status 3 if a number falls outside the accepted band "
                    f"(rise +-{TOL_RISE_C:g} degC, torque +-{TOL_TORQUE_REL:.0%}, mu +-{TOL_MU:g}).")
    parser.add_argument("--json", metavar="FILE", help="write the results as JSON {\"cases\": [...]}")
    parser.add_argument("--plots", metavar="DIR", help="write PNG figures like the paper's Figs. 3-5 into DIR")
    parser.add_argument("--dt", type=positive_number, default=1e-3, help="step [s] (default: 0.001, the plant's step)")
    add_params_option(parser)
    parser.set_defaults(func=_do_validate)


def _fmt_row(name: str, sim: float, pub: float, dev: float, ok: bool) -> str:
    if name.startswith("torque"):
        return f"{name:<20} {sim:10.2f} {pub:10.2f} {dev:+9.1%}  {'ok' if ok else 'OUTSIDE BAND'}"
    if name.startswith("mu"):
        return f"{name:<20} {sim:10.4f} {pub:10.4f} {dev:+9.4f}  {'ok' if ok else 'OUTSIDE BAND'}"
    return f"{name:<20} {sim:10.2f} {pub:10.2f} {dev:+9.2f}  {'ok' if ok else 'OUTSIDE BAND'}"


def _do_validate(args: argparse.Namespace) -> int:
    check_output_path("--json", args.json)
    check_output_path("--plots", args.plots, directory=True)
    params = params_from(args)
    if args.plots:  # fail before the long run, not after it
        from ..paper.plots import require_matplotlib
        require_matplotlib()
    from ..paper.validation import run_validation, validation_json  # noqa: PLC0415 - numpy and scipy at run time only

    results = run_validation(params, dt=args.dt, progress=progress)
    all_ok = True
    print(f"{'Section III.C':<20} {'simulated':>10} {'paper':>10} {'deviation':>9}")
    for r in results:
        ref = r.reference
        print(f"case {ref.case}: {ref.pressure_mpa} MPa, {ref.speed_rpm:g} r/min")
        for row in r.checks():
            all_ok &= bool(row[4])
            print("  " + _fmt_row(*row))
    if args.json:  # a missing directory made, as for every output (check_output_path)
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(validation_json(results), indent=2) + "\n", encoding="utf-8")
        progress(f"wrote {args.json}")
    if args.plots:
        from ..paper.plots import friction_map_figure, validation_figures
        paths = validation_figures(results, Path(args.plots))
        paths.append(friction_map_figure(params.friction, Path(args.plots) / "friction_map.png"))
        for path in paths:
            progress(f"wrote {path}")
    if not all_ok:
        raise ResultError("some numbers fall outside the accepted band (see docs/explanation/fitted.md, 'Validation')")
    return 0
