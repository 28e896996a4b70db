"""Command line: ``dsg-hil <command>``. Each command is a module with ``add_subparser`` and ``_do``.

Only the module of the command given is imported (and its modules import what the command needs when it runs),
so ``dsg-hil --help`` and ``dsg-hil COMMAND --help`` start without numpy, scipy, matplotlib or cantools.

Errors reach the user as one line ``error: ...`` (``--debug`` shows the traceback) and an exit status, the same
for ``ecu-stub`` and ``python -m ecu_stub.identify`` (one ``main``: :func:`dsg_hil.common.cli.run_main`; the tree of
errors: :mod:`dsg_hil.common.errors`): 0 ok, 1 the run failed (peer lost ...), 2 bad input or usage (the line
names the file, key or option), 3 a result outside its band (``dsg-hil validate``, ``dsg-hil dbc``), 130 Ctrl-C
(SIGINT), 143 SIGTERM (128 + the signal number, as a shell reports a killed process), at any moment from the first
line of :func:`main` (so this module imports the standard library and ``dsg_hil.common`` only).
"""

from __future__ import annotations

import argparse
import importlib
import sys

from .. import __version__
from ..common.cli import run_main
from .common import set_quiet

__all__ = ["COMMANDS", "command_help", "main"]

COMMANDS = {  # command: (module, one-line help), in the order of 'dsg-hil --help'
    "run": ("run", "run the plant and the TCU (ecu-stub) together on a bus"),
    "plant": ("plant_cmd", "run the plant process on a bus (the TCU runs elsewhere)"),
    "bridge": ("bridge_cmd", "forward frames between two buses, injecting faults into one direction"),
    "diag": ("diag_cmd", "read an ECU's DTCs (status, freeze frames) and DIDs over UDS, or clear them (extra diag)"),
    "dbc": ("dbc_cmd", "list the DBC's messages and the bus load they imply"),
    "binding": ("binding_cmd", "check a binding (plant quantities -> the DBC's signals) and print it as a table"),
    "vcan": ("vcan_cmd", "run the vcan end-to-end tests (or a command) natively or in a throw-away VM"),
    "validate": ("validate", "run the paper's single-clutch validation (Section III.C)"),
    "calibrate": ("calibrate", "re-run the calibrations of the 'calibrated' parameters"),
    "params": ("params_cmd", "list the model parameters and where each comes from"),
    "fmu": ("fmu_cmd", "write the plant as an FMI 2.0 co-simulation FMU (extra fmi)"),
    "report": ("report_cmd", "figures and a 'paper vs dsg-hil' table: validation rig and creep run"),
    "plot": ("plot_cmd", "plot one recorded run from its log: speed, pressures, plate temperatures"),
    "completion": ("completion_cmd", "print a shell completion script (bash)"),
    "sweep": ("sweep_cmd", "run a space of scenarios on Dask and judge each on the plant's truth (or --search)"),
}


def command_help(name: str) -> str:
    """The one-line help of a command (the command modules' ``add_subparser`` use it)."""
    return COMMANDS[name][1]


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="dsg-hil",
        description="CAN-bus hardware-in-the-loop plant of a DSG (dual wet clutch) creeping in traffic, "
                    "after Ma et al., 'Creeping Control Strategy for Direct Shift Gearbox ...'.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--debug", action="store_true", help="show a traceback on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    given = next((arg for arg in (sys.argv[1:] if argv is None else argv) if not arg.startswith("-")), None)
    for name, (module, help_) in COMMANDS.items():  # the top level has flags only: the first word is the command
        if name == given:
            importlib.import_module(f".{module}", __name__).add_subparser(sub)
        else:
            sub.add_parser(name, help=help_)
    for command in sub.choices.values():  # also after the command; SUPPRESS keeps a --debug given before it
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                             help="show a traceback on errors")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """``dsg-hil``: run the command given and return its exit status (argparse's usage errors exit 2 themselves)."""
    return run_main(_parse_args, argv, _dispatch, cut_short=_cut_short)


def _dispatch(args: argparse.Namespace) -> int:
    set_quiet(getattr(args, "quiet", False))  # each command afresh (several may run in one process)
    return int(args.func(args))


def _cut_short(args: argparse.Namespace, reason: str) -> None:
    """A signal ended the command: its ``cut_short`` if it has one (run, plant: the summary of a run that never
    started)."""
    cut_short = getattr(args, "cut_short", None)
    if cut_short is not None:
        cut_short(args, reason)
