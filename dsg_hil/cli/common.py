"""Helpers shared by the commands: argparse types for numbers, the parameter-file option, progress output (stderr)."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..physics.params import Params

__all__ = ["add_params_option", "params_from", "non_negative_int", "positive_number", "progress"]


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
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return value


def add_params_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--params", metavar="FILE",
                        help="parameter file (TOML; default: the one shipped with dsg-hil, see 'dsg-hil params')")


def params_from(args: argparse.Namespace) -> Params:
    from ..physics.params import load_params  # noqa: PLC0415 - when a command runs, not for its --help

    return load_params(args.params)


def progress(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


