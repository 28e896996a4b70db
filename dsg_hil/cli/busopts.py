"""Bus, scenario, log and mode options shared by ``dsg-hil plant`` and ``dsg-hil run``, and the one place they
become a :class:`~dsg_hil.sim.run.RunConfig` (:func:`run_config`).

The options need python-can only; the plant and its run (numpy, cantools ...) are imported when a run starts.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ..common.files import check_output_path
from ..protocol.bus import LOG_CHANNEL, add_bus_arguments, bus_config
from ..protocol.faults import add_fault_arguments, faults_from_args
from ..sim.scenario import load_scenario
from .common import params_from, positive_number, progress

if TYPE_CHECKING:
    from ..sim.run import RunConfig

__all__ = ["add_bus_options", "frames_line", "run_config", "setup_logging"]


def add_bus_options(parser: argparse.ArgumentParser, default_mode: str) -> None:
    add_bus_arguments(parser)
    parser.add_argument("--mode", choices=("lockstep", "realtime"), default=default_mode,
                        help=f"lockstep: the plant is the time master, as fast as both sides go, bit-for-bit "
                             f"reproducible; realtime: paced by the clock, for a real ECU (default: {default_mode})")
    parser.add_argument("--scenario", metavar="FILE", help="scenario TOML (default: the shipped creep scenario)")
    parser.add_argument("--duration", type=float, metavar="S", help="override the scenario's duration [s]")
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: dbc/dsg_hil.dbc shipped with dsg-hil)")
    parser.add_argument("--log", metavar="FILE",
                        help="write the bus traffic: .log = candump -L (canplayer, cantools), .asc, .blf, ... "
                             "by extension through python-can's writers. Timestamps in lockstep are simulated "
                             "seconds from 0 (so the 'Begin Triggerblock' line of an .asc log reads 1970); in "
                             f"real time, wall-clock time. Runs not on socketcan are logged on channel {LOG_CHANNEL}, "
                             "so 'canplayer -I FILE' replays them onto vcan0 with no mapping")
    parser.add_argument("--reply-timeout", type=positive_number, default=5.0, metavar="S",
                        help="lockstep: wall-clock seconds to wait for the TCU's answer to a tick (default 5)")
    parser.add_argument("--startup-timeout", type=positive_number, default=60.0, metavar="S",
                        help="lockstep: wall-clock seconds to wait for the TCU to answer the presence probe "
                             "before tick 0 (default 60)")
    add_fault_arguments(parser, "the frames the plant sends (side=tcu: the TCU's, 'dsg-hil run' only), besides "
                                "the scenario's [[fault]] tables")
    parser.add_argument("-v", "--verbose", action="store_true", help="log protocol events (rejected frames ...)")


def setup_logging(verbose: bool) -> None:
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")


def run_config(args: argparse.Namespace, **fields: Any) -> RunConfig:
    """The run the options describe (``fields`` set the rest, e.g. ``tcu``): output paths checked first, the
    parameters loaded (``--params``, ``--set``), the scenario loaded with the options' faults after its own, the
    bus resolved (a fresh group for udp_multicast)."""
    from ..sim.run import RunConfig  # noqa: PLC0415 - the plant (numpy ...) when a run starts

    setup_logging(args.verbose)
    for option in ("log", "summary"):
        check_output_path(f"--{option}", getattr(args, option, None))
    params = params_from(args)
    scenario = load_scenario(args.scenario)
    if args.duration is not None:
        scenario = scenario.with_duration(args.duration)
    return RunConfig(scenario=scenario, params=params, dbc=args.dbc, mode=args.mode,
                     bus=bus_config(args, fresh_udp=True), faults=[*scenario.faults, *faults_from_args(args)],
                     fault_seed=getattr(args, "fault_seed", 0), log=args.log, summary=getattr(args, "summary", None),
                     reply_timeout=args.reply_timeout, startup_timeout=args.startup_timeout, progress=progress,
                     **fields)


def frames_line(frames: Mapping[str, Any]) -> str:
    """The frame totals of a summary, in one line."""
    return (f"frames sent {frames['sent']} (re-sent {frames['retries']}), received {frames['received']}, rejected "
            f"{frames['rejected']}, lost {frames['lost']}, duplicates {frames['duplicates']}, unanswered ticks "
            f"{frames['unanswered_ticks']}")
