"""``dsg-hil params``: list every parameter with its value, unit and source."""

from __future__ import annotations

import argparse
from collections import Counter

from .common import add_params_option, params_from


def add_subparser(sub) -> None:
    parser = sub.add_parser(
        "params", help="list the model parameters and where each comes from",
        description="Load and check a parameter file, then list every value with its source: 'paper' (with the "
                    "place in the paper), 'assumed' (with the reasoning) or 'calibrated' (with the target).")
    parser.add_argument("--source", choices=("paper", "assumed", "calibrated"), help="list only this source")
    add_params_option(parser)
    parser.set_defaults(func=_do_params)


def _value(params, key: str) -> float:
    obj = params
    for part in key.split("."):
        obj = getattr(obj, part)
    return obj


def _do_params(args: argparse.Namespace) -> int:
    params = params_from(args)
    counts = Counter(source for source, _ in params.provenance.values())
    for key, (source, reason) in params.provenance.items():
        if args.source and source != args.source:
            continue
        print(f"{key:<34} {_value(params, key):>12.6g}  {source:<10} {reason}")
    print(f"# {len(params.provenance)} values: " + ", ".join(f"{counts[s]} {s}" for s in ("paper", "assumed", "calibrated")))
    return 0
