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

from ..common.errors import InputError
from ..common.files import check_output_path
from ..protocol.bus import LOG_CHANNEL, add_bus_arguments, bus_config, bus_name, require_mf4
from ..protocol.faults import add_fault_arguments, faults_from_args
from ..sim.scenario import load_scenario
from .common import params_from, positive_number, progress, set_quiet

if TYPE_CHECKING:
    from ..sim.run import RunConfig

__all__ = ["SETTING_UP", "add_bus_options", "add_verbosity_options", "frames_line", "run_config", "setup_logging",
           "started", "summary_if_unstarted"]

SETTING_UP = "dsg-hil: signal heard: stopping once the run is set up"  # said when a signal waits for that


def add_bus_options(parser: argparse.ArgumentParser, default_mode: str) -> None:
    add_bus_arguments(parser)
    parser.add_argument("--mode", choices=("lockstep", "realtime"), default=default_mode,
                        help=f"lockstep: the plant is the time master, as fast as both sides go, bit-for-bit "
                             f"reproducible; realtime: paced by the clock, for a real ECU (default: {default_mode})")
    parser.add_argument("--scenario", metavar="FILE", help="scenario TOML (default: the shipped creep scenario)")
    parser.add_argument("--duration", type=float, metavar="S", help="override the scenario's duration [s]")
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: dbc/dsg_hil.dbc shipped with dsg-hil)")
    parser.add_argument("--binding", metavar="FILE",
                        help="binding TOML: which signal of the DBC carries each quantity of the plant, in which "
                             "unit (default: dbc/dsg_hil.binding.toml, the shipped DBC's; check one with "
                             "'dsg-hil binding check')")
    parser.add_argument("--log", metavar="FILE",
                        help="write the bus traffic: .log = candump -L (canplayer, cantools), .asc, .blf, .mf4 "
                             "(ASAM MDF4: the 'mf4' extra) ... by extension through python-can's writers. "
                             "Timestamps in lockstep are simulated "
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
    add_verbosity_options(parser)


def add_verbosity_options(parser: argparse.ArgumentParser) -> None:
    """``-v``/``--verbose`` and ``-q``/``--quiet`` (see :func:`setup_logging`)."""
    loudness = parser.add_mutually_exclusive_group()
    loudness.add_argument("-v", "--verbose", action="store_true", help="log protocol events (rejected frames ...)")
    loudness.add_argument("-q", "--quiet", action="store_true",
                          help="print errors only: no progress lines, no warnings (the summary counts all)")


def setup_logging(verbose: bool, quiet: bool = False) -> None:
    """Warnings (``verbose``: protocol events too) on stderr; ``quiet``: errors only, and no progress lines."""
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    for name in ("dsg_hil", "ecu_stub"):  # set on each call: a second command in one process starts afresh
        logging.getLogger(name).setLevel(logging.ERROR if quiet else logging.NOTSET)
    set_quiet(quiet)


def run_config(args: argparse.Namespace, **fields: Any) -> RunConfig:
    """The run the options describe (``fields`` set the rest, e.g. ``tcu``): output paths checked first, the
    parameters loaded (``--params``, ``--set``), the scenario loaded with the options' faults after its own, the
    bus resolved (a fresh group for udp_multicast)."""
    from ..sim.run import RunConfig  # noqa: PLC0415 - the plant (numpy ...) when a run starts

    setup_logging(args.verbose, args.quiet)
    for option in ("log", "summary"):
        check_output_path(f"--{option}", getattr(args, option, None))
    if args.log is not None and args.log.lower().endswith(".mf4"):
        require_mf4(f"--log {args.log}")
    params = params_from(args)
    scenario = load_scenario(args.scenario)
    if args.duration is not None:
        scenario = scenario.with_duration(args.duration)
    return RunConfig(scenario=scenario, params=params, dbc=args.dbc, binding=args.binding, mode=args.mode,
                     bus=bus_config(args, fresh_udp=True), faults=[*scenario.faults, *faults_from_args(args)],
                     fault_seed=getattr(args, "fault_seed", 0), log=args.log, summary=getattr(args, "summary", None),
                     reply_timeout=args.reply_timeout, startup_timeout=args.startup_timeout, progress=progress,
                     quiet=args.quiet, **fields)


def started(args: argparse.Namespace) -> None:
    """The run is set up: from now on it writes its summary however it ends (not :func:`summary_if_unstarted`)."""
    args.run_started = True


def summary_if_unstarted(args: argparse.Namespace, reason: str) -> None:
    """``cut_short`` of ``run`` and ``plant``: a signal came before the run was set up (while the plant's modules
    loaded, the files were read, the bus opened): the ``--summary`` asked for, of zero periods, says so."""
    if not args.summary or getattr(args, "run_started", False):
        return
    from ..sim.run import unstarted_summary  # noqa: PLC0415 - the plant's modules, once a summary is due

    check_output_path("--summary", args.summary)  # bad input (not yet checked) still writes nothing
    scenario = load_scenario(args.scenario)
    duration = scenario.duration_s if args.duration is None else args.duration
    try:
        interface = bus_name(bus_config(args))  # the bus the run would have opened
    except InputError:  # one the run would not have opened
        interface = "(none)"
    unstarted_summary(reason, args.summary, scenario.name, args.mode, interface, duration,
                      getattr(args, "fault_seed", 0))
    progress(f"wrote {args.summary} (the run was {reason} before it started)")


def frames_line(frames: Mapping[str, Any]) -> str:
    """The frame totals of a summary, in one line."""
    return (f"frames sent {frames['sent']} (re-sent {frames['retries']}), received {frames['received']}, rejected "
            f"{frames['rejected']}, lost {frames['lost']}, duplicates {frames['duplicates']}, unanswered ticks "
            f"{frames['unanswered_ticks']}{_episodes(frames)}")


def _episodes(frames: Mapping[str, Any]) -> str:
    n = frames.get("unanswered_episodes", 0)
    return f" ({n} run{'s' if n > 1 else ''} of them)" if n else ""
