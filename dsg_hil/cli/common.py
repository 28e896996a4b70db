"""Helpers shared by the commands: the parameter-file option and progress output (stderr)."""

from __future__ import annotations

import argparse
import sys

from ..physics.params import Params, load_params


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that the run ends like on Ctrl-C: summary and log written."""


def raise_terminated(signum, frame) -> None:
    raise Terminated


def add_params_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--params", metavar="FILE",
                        help="parameter file (TOML; default: the one shipped with dsg-hil, see 'dsg-hil params')")


def params_from(args: argparse.Namespace) -> Params:
    return load_params(args.params)


def progress(message: str) -> None:
    print(message, file=sys.stderr, flush=True)
