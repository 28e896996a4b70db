"""``dsg-hil run``: the plant and the TCU together, and a summary of what happened."""

from __future__ import annotations

import argparse
import time
from contextlib import ExitStack
from typing import TYPE_CHECKING


from . import command_help
from ..common.cli import signals_held
from ..common.errors import InputError
from .busopts import SETTING_UP, add_bus_options, frames_line, run_config, started, summary_if_unstarted
from .common import add_params_option, progress

if TYPE_CHECKING:
    from ..fmi.controller import ControllerFmu

__all__ = ["add_subparser"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "run", help=command_help("run"),
        description="Run a scenario with the plant and the TCU: as two processes on a real bus (socketcan, "
                    "udp_multicast, ...: the TCU is started as 'ecu-stub' with the same bus options), or in one "
                    "process on python-can's 'virtual' interface. With no interface configured and no vcan0 "
                    "present, runs on 'virtual' in lockstep, so it works on any machine.")
    add_bus_options(parser, default_mode="lockstep")
    parser.add_argument("--summary", metavar="FILE", help="write a JSON summary (creep and slip times, "
                        "peak temperatures, handovers, stop reason, frame counts)")
    add_params_option(parser)
    parser.add_argument("--calibration", metavar="FILE",
                        help="the TCU's (ecu-stub's) calibration TOML, e.g. one 'python -m ecu_stub.identify "
                             "--write' made (default: ecu_stub/data/calibration.toml)")
    parser.add_argument("--controller", metavar="FMU", help="the TCU's controller: a co-simulation FMU (FMI 2.0, "
                        "e.g. from Simulink) run through FMPy behind ecu-stub's bus side, in this process (interface "
                        "virtual); its variables matched to the DBC's signals by name (extra fmi)")
    parser.add_argument("--controller-map", metavar="FILE", help="for --controller: TOML lines "
                        "'\"FMU variable\" = \"DBC signal\"' where the names differ")
    parser.set_defaults(func=_do_run, cut_short=summary_if_unstarted)


def _do_run(args: argparse.Namespace) -> int:
    if args.controller_map is not None and args.controller is None:  # else ignored: a bad file would pass unseen
        raise InputError(f"--controller-map {args.controller_map}: maps a controller FMU's variables: give "
                         f"--controller FMU too")
    with ExitStack() as stack:
        with signals_held(SETTING_UP):  # a signal now: the run ends once set up, its summary written
            from ..sim.run import open_run  # noqa: PLC0415 - the plant (numpy ...) when a run starts

            tcu = {} if args.controller is None else {"tcu": stack.enter_context(_controller(args)).tcu_factory}
            run = stack.enter_context(open_run(run_config(args, calibration=args.calibration, **tcu)))
            started(args)
        progress(f"run: {run.scenario.name}, {run.scenario.duration_s:g} s, {args.mode} on {run.interface}")
        t0 = time.monotonic()
        summary = run.run()
        wall = time.monotonic() - t0
    if args.summary:
        progress(f"wrote {args.summary}")
    progress(f"done: {run.scenario.duration_s:g} simulated s in {wall:.1f} s wall; stop: {summary.stop_reason}; "
             f"handovers: {len(summary.handovers)}; {frames_line(summary.frames)}")
    return 0


def _controller(args: argparse.Namespace) -> ControllerFmu:
    from ..fmi.controller import open_controller  # noqa: PLC0415 - the package (fmpy: when the FMU is opened)

    return open_controller(args.controller, args.controller_map)
