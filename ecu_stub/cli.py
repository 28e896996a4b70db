"""``ecu-stub`` (also ``python -m ecu_stub``): the TCU process on a CAN bus."""

from __future__ import annotations

import argparse
import logging
import sys

from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.protocol.bus import open_bus, resolve_bus_config

from .calibration import load_calibration
from .controller import CreepController
from .runner import TCU_USES, TcuRunner


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="ecu-stub",
        description="Transmission control unit with the paper's creep strategy: engages CL first (hill-hold and "
                    "pre-fill), tracks the desired creep speed with clutch pressure, predicts both plate temperatures "
                    "with its calibrated model, hands the torque over to the other clutch before the slipping one can "
                    "pass 250 degC, and stops the vehicle when neither can take over. Knows the plant only through "
                    "the DBC. Answers SIM_SYNC ticks when the plant runs in lockstep, else runs on its own clock at "
                    "the TCU_CMD cycle time.")
    parser.add_argument("--interface", "-i", metavar="I", help="python-can interface (default: python-can config, "
                        "else socketcan on vcan0 where it exists, else virtual)")
    parser.add_argument("--channel", "-c", metavar="C", help="python-can channel")
    parser.add_argument("--config-context", metavar="SECTION", help="section of the python-can config file")
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: the one shipped with dsg-hil)")
    parser.add_argument("--calibration", metavar="FILE",
                        help="TCU calibration TOML (default: ecu_stub/data/calibration.toml)")
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: never)")
    parser.add_argument("--idle-exit", type=float, metavar="S",
                        help="stop when the plant has been silent for S seconds after having been heard")
    parser.add_argument("-v", "--verbose", action="store_true", help="log protocol events")
    parser.add_argument("--debug", action="store_true", help="show a traceback on errors")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = _parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        controller = CreepController(load_calibration(args.calibration))
        config = resolve_bus_config(args.interface, args.channel, args.config_context)
        codec = Codec(load_dbc(args.dbc), TCU_USES)
        bus = open_bus(config)
        print(f"ecu-stub: listening on {config['interface']}:{config['channel']}", file=sys.stderr, flush=True)
        try:
            TcuRunner(codec, bus, controller).run(duration=args.duration, idle_timeout=args.idle_exit)
        finally:
            bus.shutdown()
    except KeyboardInterrupt:
        return 0
    except Exception as exc:  # noqa: BLE001 - the CLI's single exit point for errors
        if args.debug:
            raise
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0
