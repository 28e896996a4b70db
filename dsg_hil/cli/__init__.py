"""Command line: ``dsg-hil <command>``. Each command is a module with ``add_subparser`` and ``_do``.

Errors reach the user as one line ``error: ...`` (``--debug`` shows the traceback) and an exit status, the same
for ``ecu-stub`` (:mod:`dsg_hil.errors`): 0 ok, 1 the run failed (peer lost ...), 2 bad input or usage (the line
names the file, key or option), 3 a result outside its band (``dsg-hil validate``), 130 Ctrl-C (SIGINT), 143
SIGTERM (128 + the signal number, as a shell reports a killed process).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from .. import __version__
from ..errors import EXIT_RUN_FAILED, EXIT_SIGINT, EXIT_SIGTERM, exit_code
from . import bridge_cmd, calibrate, dbc_cmd, params_cmd, plant_cmd, report_cmd, run, validate, vcan_cmd
from .common import Terminated, raise_terminated

COMMANDS = (run, plant_cmd, bridge_cmd, dbc_cmd, vcan_cmd, validate, calibrate, params_cmd, report_cmd)
EXIT_ERROR = EXIT_RUN_FAILED


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="dsg-hil",
        description="CAN-bus hardware-in-the-loop plant of a DSG (dual wet clutch) creeping in traffic, "
                    "after Ma et al., 'Creeping Control Strategy for Direct Shift Gearbox ...'.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--debug", action="store_true", help="show a traceback on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in COMMANDS:
        module.add_subparser(sub)
    for command in sub.choices.values():  # also after the command; SUPPRESS keeps a --debug given before it
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                             help="show a traceback on errors")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = _parse_args(argv)
    main_thread = threading.current_thread() is threading.main_thread()  # only there can signals be handled
    previous = signal.signal(signal.SIGTERM, raise_terminated) if main_thread else None
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return EXIT_SIGINT
    except Terminated:
        print("error: terminated", file=sys.stderr)
        return EXIT_SIGTERM
    except Exception as exc:  # noqa: BLE001 - the CLI's single exit point for errors
        if args.debug:
            raise
        print(f"error: {exc}", file=sys.stderr)
        return exit_code(exc)
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous)
