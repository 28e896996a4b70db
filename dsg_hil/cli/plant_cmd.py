"""``dsg-hil plant``: the plant alone on a bus, for a TCU started separately (ecu-stub or a real ECU)."""

from __future__ import annotations

import argparse
import shlex
from contextlib import ExitStack

from ..protocol.bus import bus_args, per_process_warning
from . import command_help
from ..common.cli import signals_held
from .busopts import SETTING_UP, add_bus_options, frames_line, run_config, started, summary_if_unstarted
from .common import add_params_option, progress

__all__ = ["add_subparser"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "plant", help=command_help("plant"),
        description="Run the plant on a CAN bus against a TCU started separately (ecu-stub, or a real ECU on "
                    "can0). Real time by default: frames at their DBC cycle times, commands used as they "
                    "arrive, unpowered hydraulics when TCU_CMD is missing for 3 cycle times. Lockstep: the "
                    "plant waits for the TCU's answer to each SIM_SYNC tick. Two processes on one machine "
                    "without vcan: -i udp_multicast (the plant picks a group and port for the run and prints "
                    "the ecu-stub command that joins it). Exit 1 (stop reason no_peer, the summary written) when "
                    "no TCU was heard: in lockstep none answered the presence probe; in real time not one TCU "
                    "frame came in the whole run (a mistyped channel or port must not look like a clean run).")
    add_bus_options(parser, default_mode="realtime")
    parser.add_argument("--summary", metavar="FILE", help="write the JSON summary at the end")
    add_params_option(parser)
    parser.set_defaults(func=_do_plant, cut_short=summary_if_unstarted)


def _do_plant(args: argparse.Namespace) -> int:
    with ExitStack() as stack:
        with signals_held(SETTING_UP):  # a signal now: the run ends once set up, its summary written
            from ..sim.run import EcuStubProcess, open_run  # noqa: PLC0415 - the plant (numpy ...) when a run starts
            from ..sim.runner import PeerTimeout  # noqa: PLC0415

            run = stack.enter_context(open_run(run_config(args, tcu=None)))
            started(args)
        progress(f"plant: {run.scenario.name}, {run.scenario.duration_s:g} s, {args.mode} on {run.interface}")
        warning = per_process_warning(run.bus_config)
        progress(f"warning: {warning}" if warning else f"TCU: ecu-stub {shlex.join(bus_args(run.bus_config))} "
                 f"--idle-exit {EcuStubProcess.idle_exit:g}")  # it ends once the plant has gone, as run's does
        try:
            summary = run.run()
        except PeerTimeout as exc:  # (PeerLost too: the type decides the summary's stop reason)
            if warning:
                raise type(exc)(f"{exc} ({warning})") from None
            raise
    if args.summary:
        progress(f"wrote {args.summary}")
    progress(f"done: stop {summary.stop_reason}; {frames_line(summary.frames)}")
    return 0
