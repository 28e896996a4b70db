"""``dsg-hil params``: list every parameter with its value, unit and source."""

from __future__ import annotations

import argparse
from collections import Counter
from dataclasses import fields
from typing import TYPE_CHECKING

from . import command_help
from .common import add_params_option, params_from

if TYPE_CHECKING:
    from ..physics.params import Params

__all__ = ["add_subparser"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "params", help=command_help("params"),
        description="Load and check a parameter file, then list every value with its source: 'paper' (with the "
                    "place in the paper), 'assumed' (with the reasoning) or 'calibrated' (with the target).")
    parser.add_argument("--source", choices=("paper", "assumed", "calibrated", "override"),
                        help="list only this source (override: the values --set changed)")
    add_params_option(parser)
    parser.set_defaults(func=_do_params)


def _value_and_unit(params: Params, key: str) -> tuple[float, str]:
    """The value at a dotted key and the unit its dataclass field declares."""
    *path, name = key.split(".")
    obj = params
    for part in path:
        obj = getattr(obj, part)
    unit = next(f.metadata.get("unit", "") for f in fields(obj) if f.name == name)
    return getattr(obj, name), unit


def _do_params(args: argparse.Namespace) -> int:
    params = params_from(args)
    counts = Counter(source for source, _ in params.provenance.values())
    for key, (source, reason) in params.provenance.items():
        if args.source and source != args.source:
            continue
        value, unit = _value_and_unit(params, key)
        print(f"{key:<34} {value:>12.6g} {unit:<9} {source:<10} {reason}")
    sources = ("paper", "assumed", "calibrated", *(("override",) if counts["override"] else ()))
    print(f"# {len(params.provenance)} values: " + ", ".join(f"{counts[s]} {s}" for s in sources))
    return 0
