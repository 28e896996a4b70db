"""``dsg-hil plant``: the plant alone on a bus, for a TCU started separately (ecu-stub or a real ECU)."""

from __future__ import annotations

import argparse
import shlex
from contextlib import ExitStack

from ..protocol.bus import bus_args, per_process_warning
from ..protocol.faults import FaultError
from . import command_help
from .busopts import add_bus_options, drive, finish, frames_line, start
from .common import add_params_option, progress


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "plant", help=command_help("plant"),
        description="Run the plant on a CAN bus against a TCU started separately (ecu-stub, or a real ECU on "
                    "can0). Real time by default: frames at their DBC cycle times, commands used as they "
                    "arrive, unpowered hydraulics when TCU_CMD is missing for 3 cycle times. Lockstep: the "
                    "plant waits for the TCU's answer to each SIM_SYNC tick. Two processes on one machine "
                    "without vcan: -i udp_multicast (the plant picks a group and port for the run and prints "
                    "the ecu-stub command that joins it).")
    add_bus_options(parser, default_mode="realtime")
    parser.add_argument("--summary", metavar="FILE", help="write the JSON summary at the end")
    add_params_option(parser)
    parser.set_defaults(func=_do_plant)


def _do_plant(args: argparse.Namespace) -> int:
    from ..sim.runner import PeerTimeout  # noqa: PLC0415 - the plant (numpy ...) when a run starts

    with ExitStack() as stack:
        runner, config, scenario = start(args, stack, "plant")
        if args.faults_by_side["tcu"]:
            raise FaultError(f"{args.faults_by_side['tcu'][0].origin}: changes the TCU's frames: give it to "
                             f"ecu-stub (--fault), not to the plant")
        warning = per_process_warning(config)
        progress(f"warning: {warning}" if warning else f"TCU: ecu-stub {shlex.join(bus_args(config))}")
        try:
            drive(runner, args)
        except PeerTimeout as exc:  # (PeerLost too: the type decides the summary's stop reason)
            if warning:
                raise type(exc)(f"{exc} ({warning})") from None
            raise
        summary = finish(args, runner, config, scenario)
    progress(f"done: stop {summary['stop_reason']}; {frames_line(summary['frames'])}")
    return 0
