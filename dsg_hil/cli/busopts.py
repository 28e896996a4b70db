"""Bus, scenario, log and mode options shared by ``dsg-hil plant`` and ``dsg-hil run``."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from contextlib import ExitStack
from pathlib import Path

import can

from ..physics.thermal import NODES
from ..plant import Plant
from ..plant_io import PLANT_USES
from ..protocol import Codec, load_dbc
from ..protocol.bus import open_bus, resolve_bus_config
from ..runner import PlantRunner
from ..scenario import Scenario, load_scenario
from .common import params_from, progress


def add_bus_options(parser: argparse.ArgumentParser, default_mode: str) -> None:
    parser.add_argument("--interface", "-i", metavar="I",
                        help="python-can interface (socketcan, virtual, ...); default: can.rc / CAN_INTERFACE / "
                             "~/.canrc, else socketcan on vcan0 where it exists, else virtual")
    parser.add_argument("--channel", "-c", metavar="C", help="python-can channel (vcan0, can0, ...)")
    parser.add_argument("--config-context", metavar="SECTION", help="section of the python-can config file")
    parser.add_argument("--mode", choices=("lockstep", "realtime"), default=default_mode,
                        help=f"lockstep: the plant is the time master, as fast as both sides go, bit-for-bit "
                             f"reproducible; realtime: paced by the clock, for a real ECU (default: {default_mode})")
    parser.add_argument("--scenario", metavar="FILE", help="scenario TOML (default: the shipped creep scenario)")
    parser.add_argument("--duration", type=float, metavar="S", help="override the scenario's duration [s]")
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: dbc/dsg_hil.dbc shipped with dsg-hil)")
    parser.add_argument("--log", metavar="FILE",
                        help="write the bus traffic: .log = candump -L (canplayer, cantools), .asc, .blf, ... "
                             "by extension through python-can's writers")
    parser.add_argument("--reply-timeout", type=float, default=5.0, metavar="S",
                        help="lockstep: wall-clock seconds to wait for the TCU's answer to a tick (default 5)")
    parser.add_argument("--startup-timeout", type=float, default=60.0, metavar="S",
                        help="lockstep: wall-clock seconds to wait for the TCU to answer the presence probe "
                             "before tick 0 (default 60)")
    parser.add_argument("-v", "--verbose", action="store_true", help="log protocol events (rejected frames ...)")


def setup_logging(verbose: bool) -> None:
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")


def scenario_from(args: argparse.Namespace) -> Scenario:
    scenario = load_scenario(args.scenario)
    return scenario.with_duration(args.duration) if args.duration is not None else scenario


def make_plant(args: argparse.Namespace, scenario: Scenario) -> Plant:
    return Plant(params_from(args), T_init=scenario.initial_temperatures(NODES), v_init=scenario.v_mps)


class LogListener:
    """Writes frames through python-can's writer for the file's extension, on one channel name."""

    def __init__(self, path: str, channel: str) -> None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        try:
            self.writer = can.Logger(path)
        except ValueError as exc:
            raise ValueError(f"--log {path}: {exc}") from None
        self.channel = channel

    def __call__(self, msg: can.Message) -> None:
        msg.channel = self.channel
        self.writer.on_message_received(msg)

    def stop(self) -> None:
        self.writer.stop()


def start(args: argparse.Namespace, stack: ExitStack, what: str) -> tuple[PlantRunner, dict, Scenario]:
    """Logging, scenario, the plant's bus and log from the options, announced; all closed by ``stack``."""
    setup_logging(args.verbose)
    scenario = scenario_from(args)
    runner, config = plant_runner(args, stack, scenario)
    progress(f"{what}: {scenario.name}, {scenario.duration_s:g} s, {args.mode} on "
             f"{config['interface']}:{config['channel']}")
    return runner, config, scenario


def plant_runner(args: argparse.Namespace, stack: ExitStack, scenario: Scenario) -> tuple[PlantRunner, dict]:
    """Open the plant's bus (and log) from the options; everything is closed by ``stack``."""
    config = resolve_bus_config(args.interface, args.channel, args.config_context)
    db = load_dbc(args.dbc)
    bus = open_bus(config)
    stack.callback(bus.shutdown)
    listeners = ()
    if args.log:
        listener = LogListener(args.log, str(config["channel"]))
        stack.callback(listener.stop)
        listeners = (listener,)
    runner = PlantRunner(make_plant(args, scenario), scenario, Codec(db, PLANT_USES), bus, listeners, progress)
    return runner, config


def drive(runner: PlantRunner, args: argparse.Namespace, pump=None) -> None:
    """Run the scenario in the chosen mode (``pump``: an in-process TCU on the virtual bus, lockstep)."""
    if args.mode == "lockstep":
        runner.run_lockstep(args.reply_timeout, pump=pump, startup_timeout=args.startup_timeout)
    else:
        runner.run_realtime()


def finish(args: argparse.Namespace, runner: PlantRunner, config: dict, scenario: Scenario, **extra) -> dict:
    """The run's summary (written to --summary if given)."""
    summary = runner.summary.as_json(runner.frames(), scenario.name, args.mode,
                                     f"{config['interface']}:{config['channel']}", scenario.duration_s)
    summary.update(extra)
    if args.summary:
        Path(args.summary).parent.mkdir(parents=True, exist_ok=True)
        Path(args.summary).write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
        progress(f"wrote {args.summary}")
    return summary
