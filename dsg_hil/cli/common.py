"""Helpers shared by the commands: argparse types for numbers, the parameter-file option, progress output (stderr)."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..physics.params import Params

__all__ = ["add_params_option", "non_negative_int", "params_from", "positive_int", "positive_number", "progress",
           "set_overrides", "set_quiet"]


def positive_number(text: str) -> float:
    """An argparse type: a finite number > 0 (else a usage error, exit 2)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def non_negative_int(text: str) -> int:
    """An argparse type: a whole number >= 0 (else a usage error, exit 2)."""
    return _whole_at_least(text, 0)


def positive_int(text: str) -> int:
    """An argparse type: a whole number >= 1 (else a usage error, exit 2): a count of runs or workers."""
    return _whole_at_least(text, 1)


def _whole_at_least(text: str, low: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < low:
        raise argparse.ArgumentTypeError(f"must be >= {low}, got {text}")
    return value


def add_params_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--params", metavar="FILE|NAME",
                        help="parameter file (TOML) layered on the one shipped with dsg-hil: it may give only the "
                             "keys it changes (see 'dsg-hil params'); or a configuration's name: 'fitted' (the "
                             "shipped file, default) or 'table1' (Table I and stated assumptions alone)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one parameter after --params, by its dotted key as 'dsg-hil params' lists "
                             "it, in the unit listed there (optionally stated: vehicle.m=9000 or "
                             "'vehicle.m=9000 kg'; no conversion); repeatable")


def params_from(args: argparse.Namespace) -> Params:
    """The parameters the options give: the shipped file, ``--params`` layered on it, then each ``--set``."""
    from ..physics.params import load_params, with_overrides  # noqa: PLC0415 - not for --help

    params = load_params(args.params)
    overrides = set_overrides(args)
    return with_overrides(params, overrides, origin="--set") if overrides else params


def set_overrides(args: argparse.Namespace) -> dict[str, str]:
    """``--set KEY=VALUE`` options as ``{dotted key: value text}`` (not yet checked against the parameters)."""
    from ..physics.params import ParameterError  # noqa: PLC0415 - not for --help

    overrides: dict[str, str] = {}
    for assignment in getattr(args, "set", None) or ():
        key, equals, value = assignment.partition("=")
        if not equals or not key.strip():
            raise ParameterError(f"--set: expected KEY=VALUE (e.g. vehicle.m=9000), got {assignment!r}")
        overrides[key.strip()] = value
    return overrides


_quiet = [False]  # set by each command (``--quiet``; see busopts.setup_logging)


def set_quiet(quiet: bool) -> None:
    """Whether :func:`progress` prints (``--quiet``: it does not)."""
    _quiet[0] = quiet


def progress(message: str) -> None:
    """One progress line on stderr (none under ``--quiet``)."""
    if not _quiet[0]:
        print(message, file=sys.stderr, flush=True)


