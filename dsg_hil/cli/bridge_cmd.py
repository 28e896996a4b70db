"""``dsg-hil bridge``: forward frames between two buses, with faults on the way (e.g. a real ECU on can0 and the
plant on vcan0: the ECU's frames reach the plant through the injector, the plant's reach the ECU unchanged)."""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from contextlib import ExitStack
from typing import TYPE_CHECKING

import can.cli

from ..protocol.faults import add_fault_arguments
from . import command_help
from .common import positive_number, progress

if TYPE_CHECKING:
    from ..protocol.faults import FaultInjector

__all__ = ["add_subparser", "bridge"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "bridge", help=command_help("bridge"),
        description="Forward every frame from the --from bus to the --to bus through the faults given, and every "
                    "frame from --to back to --from unchanged. "
                    "For a node whose software cannot be changed: put it alone on --from (e.g. a real ECU on "
                    "can0) and the plant on --to (e.g. vcan0, dsg-hil plant in real time).")
    for end in ("from", "to"):  # python-can's bus options, each end's prefixed (--from-bus-kwargs port=...)
        can.cli.add_bus_arguments(parser, prefix=end, group_title=f"the {end} bus (python-can's options)")
        for action in parser._actions:
            if action.dest in (f"{end}_interface", f"{end}_channel"):
                action.required = True
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: the one shipped with dsg-hil)")
    parser.add_argument("--duration", type=positive_number, metavar="S", help="stop after S seconds (default: "
                        "never; Ctrl-C)")
    add_fault_arguments(parser, "the frames going from --from to --to (side is not used: every fault applies)",
                        times="seconds since the bridge started (the wall clock: the bridge sees no lockstep)")
    parser.set_defaults(func=_do_bridge)


def bridge(source: can.BusABC, sink: can.BusABC, injector: FaultInjector, clock: Callable[[], float],
           should_stop: Callable[[], bool]) -> tuple[int, int]:
    """Forward source -> sink through ``injector`` at ``clock()`` and sink -> source unchanged until
    ``should_stop()``; returns how many frames went each way."""
    from ..protocol.faults import bridge_step  # noqa: PLC0415 - python-can and cantools at run time only
    forward = back = 0
    while not should_stop():
        forward += bridge_step(source, sink, injector, clock(), timeout=0.001)
        while (msg := sink.recv(timeout=0.0)) is not None:
            source.send(msg)
            back += 1
    return forward, back


def _do_bridge(args: argparse.Namespace) -> int:
    from ..protocol import load_dbc  # noqa: PLC0415 - python-can and cantools at run time only
    from ..protocol.bus import bus_config, bus_name, has_fd, open_bus  # noqa: PLC0415
    from ..protocol.faults import FaultInjector, faults_from_args  # noqa: PLC0415

    db = load_dbc(args.dbc)
    injector = FaultInjector(db, faults_from_args(args), args.fault_seed)
    configs = [bus_config(args, prefix=end) for end in ("from", "to")]
    with ExitStack() as stack:
        source, sink = (open_bus(config, fd=has_fd(db.messages)) for config in configs)  # (a CAN FD matrix: FD)
        stack.callback(source.shutdown)
        stack.callback(sink.shutdown)
        progress(f"bridge: {bus_name(configs[0])} -> {bus_name(configs[1])} through "
                 f"{len(injector.specs)} fault(s); back unchanged")
        start = time.monotonic()
        clock = lambda: time.monotonic() - start  # noqa: E731
        try:
            forward, back = bridge(source, sink, injector, clock,
                                   lambda: args.duration is not None and clock() >= args.duration)
        finally:
            progress(f"bridge: faults injected (frames hit): {injector.hits()}")
    progress(f"bridge: forwarded {forward} frames, {back} back")
    return 0
