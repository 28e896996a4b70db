"""Bus, scenario, log and mode options shared by ``dsg-hil plant`` and ``dsg-hil run``.

The options need python-can only; the plant and its run (numpy, cantools ...) are imported when a run starts.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

from ..protocol.bus import LOG_CHANNEL, FrameLog, add_bus_arguments, bus_config, bus_name, log_channel, open_bus
from ..protocol.faults import add_fault_arguments, check_faults, faults_from_args
from ..sim.scenario import Scenario, load_scenario
from ..common.files import check_output_path
from .common import Terminated, params_from, positive_number, progress

if TYPE_CHECKING:
    import can

    from ..physics.plant import Plant
    from ..sim.runner import PlantRunner


def stop_reasons() -> tuple[tuple[type[BaseException], str], ...]:
    """How a run that ends early ends: the exception and the summary's stop reason."""
    from ..sim.runner import PeerLost, PeerTimeout  # noqa: PLC0415 - the plant (numpy ...) when a run starts

    return ((KeyboardInterrupt, "interrupted"), (Terminated, "terminated"), (PeerLost, "peer_lost"),
            (PeerTimeout, "no_peer"))  # after PeerLost, its subclass: no TCU answered the presence probe


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


def scenario_from(args: argparse.Namespace) -> Scenario:
    scenario = load_scenario(args.scenario)
    return scenario.with_duration(args.duration) if args.duration is not None else scenario


def make_plant(args: argparse.Namespace, scenario: Scenario) -> Plant:
    from ..sim.loop import plant_for  # noqa: PLC0415 - the plant (numpy ...) when a run starts

    return plant_for(scenario, params_from(args))


def start(args: argparse.Namespace, stack: ExitStack, what: str) -> tuple[PlantRunner, dict, Scenario]:
    """Logging, scenario, the plant's bus and log from the options, announced; all closed by ``stack``."""
    setup_logging(args.verbose)
    for option in ("log", "summary"):
        check_output_path(f"--{option}", getattr(args, option, None))
    scenario = scenario_from(args)
    runner, config = plant_runner(args, stack, scenario)
    stack.push(_summary_on_abort(args, runner, config, scenario))
    progress(f"{what}: {scenario.name}, {scenario.duration_s:g} s, {args.mode} on {bus_name(config)}")
    return runner, config, scenario


def _summary_on_abort(args: argparse.Namespace, runner: PlantRunner, config: dict,
                      scenario: Scenario) -> Callable[..., bool]:
    """An exit handler (ExitStack.push) that writes the summary so far when the run ends early: Ctrl-C,
    SIGTERM or a lost peer (stop reasons interrupted, terminated, peer_lost)."""
    reasons = stop_reasons()

    def on_exit(exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> bool:
        reason = next((r for kind, r in reasons if exc_type is not None and issubclass(exc_type, kind)), None)
        if reason is not None:
            runner.summary.stop_reason = reason
            finish(args, runner, config, scenario)
        return False
    return on_exit


def plant_runner(args: argparse.Namespace, stack: ExitStack, scenario: Scenario) -> tuple[PlantRunner, dict]:
    """Open the plant's bus (and log) from the options; everything is closed by ``stack``.

    ``args.tcu_in_process`` (``dsg-hil run``, ``report``) on ``virtual`` in lockstep: the plant and the TCU of
    this process talk over a direct in-process bus instead (:mod:`dsg_hil.protocol.local`: the same frames,
    without python-can's copies), the TCU's end left in ``args.tcu_bus``."""
    from ..sim.plant_io import PLANT_RX, PLANT_USES  # noqa: PLC0415 - the plant (numpy, cantools ...) when a run starts
    from ..protocol import Codec, load_dbc  # noqa: PLC0415
    from ..protocol.local import local_pair  # noqa: PLC0415
    from ..sim.runner import PlantRunner  # noqa: PLC0415

    config = bus_config(args, fresh_udp=True)
    db = load_dbc(args.dbc)
    args.faults_by_side = check_faults([*scenario.faults, *faults_from_args(args)], db)
    if getattr(args, "tcu_in_process", False) and config["interface"] == "virtual" and args.mode == "lockstep":
        plant_end, args.tcu_bus = local_pair(str(config["channel"]))
        stack.callback(args.tcu_bus.shutdown)
        bus: can.BusABC = plant_end
    else:
        bus = open_bus(config, receive=[db.get_message_by_name(name) for name in PLANT_RX])
    stack.callback(bus.shutdown)
    listeners: tuple[FrameLog, ...] = ()
    if args.log:
        listener = FrameLog(args.log, log_channel(config))
        stack.callback(listener.stop)
        listeners = (listener,)
    runner = PlantRunner(make_plant(args, scenario), scenario, Codec(db, PLANT_USES), bus, listeners, progress)
    runner.inject(args.faults_by_side["plant"], getattr(args, "fault_seed", 0))
    if runner.bus is not bus:
        stack.callback(runner.bus.shutdown)
    return runner, config


def drive(runner: PlantRunner, args: argparse.Namespace, pump: Callable[[], None] | None = None) -> None:
    """Run the scenario in the chosen mode (``pump``: an in-process TCU on the virtual bus, lockstep)."""
    if args.mode == "lockstep":
        runner.run_lockstep(args.reply_timeout, pump=pump, startup_timeout=args.startup_timeout)
    else:
        runner.run_realtime()


def frames_line(frames: dict) -> str:
    """The frame totals of a summary, in one line."""
    return (f"frames sent {frames['sent']} (re-sent {frames['retries']}), received {frames['received']}, rejected "
            f"{frames['rejected']}, lost {frames['lost']}, duplicates {frames['duplicates']}, unanswered ticks "
            f"{frames['unanswered_ticks']}")


def finish(args: argparse.Namespace, runner: PlantRunner, config: dict, scenario: Scenario,
           **extra: object) -> dict:
    """The run's summary (written to --summary if given)."""
    summary = runner.summary.as_json(runner.frames(), scenario.name, args.mode, bus_name(config),
                                     scenario.duration_s)
    summary["sim_time_s"] = round(runner.plant.state.t, 3)  # where the run ended (< duration_s if cut short)
    summary["faults"] = runner.fault_summary()
    summary.update(extra)
    if args.summary:
        Path(args.summary).parent.mkdir(parents=True, exist_ok=True)
        Path(args.summary).write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
        progress(f"wrote {args.summary}")
    return summary
