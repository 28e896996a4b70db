"""``dsg-hil run``: the plant and the TCU together, and a summary of what happened."""

from __future__ import annotations

import argparse
import time

from . import command_help
from .busopts import add_bus_options, frames_line, run_config
from .common import add_params_option, progress

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
    parser.set_defaults(func=_do_run)


def _do_run(args: argparse.Namespace) -> int:
    from ..sim.run import open_run  # noqa: PLC0415 - the plant (numpy ...) when a run starts

    with open_run(run_config(args)) as run:
        progress(f"run: {run.scenario.name}, {run.scenario.duration_s:g} s, {args.mode} on {run.interface}")
        t0 = time.monotonic()
        summary = run.run()
        wall = time.monotonic() - t0
    if args.summary:
        progress(f"wrote {args.summary}")
    progress(f"done: {run.scenario.duration_s:g} simulated s in {wall:.1f} s wall; stop: {summary.stop_reason}; "
             f"handovers: {len(summary.handovers)}; {frames_line(summary.frames)}")
    return 0
