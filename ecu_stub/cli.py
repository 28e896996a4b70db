"""``ecu-stub`` (also ``python -m ecu_stub``): the TCU process on a CAN bus.

Exit status as dsg-hil's (:func:`dsg_hil.common.cli.run_main`): 0 at ``--duration`` or ``--idle-exit``, 1 the run
failed, 2 bad input or usage (one ``error:`` line naming the file or option), 130 Ctrl-C, 143 SIGTERM (serving
stops, the frame counts are printed).
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
from collections.abc import Mapping
from importlib import metadata

from dsg_hil.protocol.bus import (FrameLog, add_bus_arguments, bus_config, bus_name, log_channel, open_bus,
                                  per_process_warning)
from dsg_hil.common.cli import run_main
from dsg_hil.common.errors import InputError
from dsg_hil.common.files import check_output_path
from dsg_hil.protocol.faults import FaultError, add_fault_arguments, check_faults, faults_from_args, with_faults

__all__ = ["EXAMPLE_FAULTS", "by_cause", "main"]

EXAMPLE_FAULTS = ("drop:TCU_CMD@10-12", "stuck:TCU_STATUS.T_CL_Pred@5-8,value=20")  # --help: the TCU's own frames


def _version() -> str:
    """The version of the dsg-hil distribution that ships ecu-stub (dsg_hil.__version__, through its metadata)."""
    try:
        return metadata.version("dsg-hil")
    except metadata.PackageNotFoundError:
        return "(dsg-hil not installed)"


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="ecu-stub",
        description="Transmission control unit with the paper's creep strategy: engages CL first (hill-hold and "
                    "pre-fill), tracks the desired creep speed with clutch pressure, predicts both plate temperatures "
                    "with its calibrated model, hands the torque over to the other clutch before the slipping one can "
                    "pass 250 degC, and stops the vehicle when neither can take over. Knows the plant only through "
                    "the DBC. Answers SIM_SYNC ticks when the plant runs in lockstep, else runs on its own clock at "
                    "the TCU_CMD cycle time.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    add_bus_arguments(parser, fresh_udp=False)
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: the one shipped with dsg-hil)")
    parser.add_argument("--calibration", metavar="FILE",
                        help="TCU calibration TOML (default: ecu_stub/data/calibration.toml)")
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: never)")
    add_fault_arguments(parser, "the frames the TCU sends", EXAMPLE_FAULTS)
    parser.add_argument("--log", metavar="FILE",
                        help="record the frames the TCU took and sent (first transmissions; lockstep: stamped "
                             "with simulated time), in python-can's format for the extension: .log (candump -L), "
                             ".asc, .blf, .csv ...")
    parser.add_argument("--idle-exit", type=float, metavar="S",
                        help="stop when the plant has been silent for S seconds after having been heard")
    parser.add_argument("-v", "--verbose", action="store_true", help="log protocol events")
    parser.add_argument("--debug", action="store_true", help="show a traceback on errors")
    return parser.parse_args(argv)


def by_cause(rejected: Mapping[str, int]) -> str:
    """' (crc 3, dlc 12)': the rejects by cause, sorted, for the closing line; '' when there were none."""
    causes = ", ".join(f"{reason} {n}" for reason, n in sorted(rejected.items()) if n)
    return f" ({causes})" if causes else ""


def main(argv: list[str] | None = None) -> int:
    """``ecu-stub``: serve until ``--duration``, ``--idle-exit``, Ctrl-C or SIGTERM; returns the exit status."""
    stop = threading.Event()  # SIGTERM: stop serving, report the counts, exit 143
    return run_main(_parse_args, argv, lambda args: _serve(args, stop), stop)


def _serve(args: argparse.Namespace, stop: threading.Event) -> None:
    from dsg_hil.protocol import Codec, load_dbc  # noqa: PLC0415 - cantools when serving, not for --help

    from .calibration import load_calibration  # noqa: PLC0415
    from .controller import CreepController  # noqa: PLC0415
    from .runner import TCU_RX, TCU_USES, TcuRunner  # noqa: PLC0415

    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    for option in ("duration", "idle_exit"):
        value = getattr(args, option)
        if value is not None and not 0.0 < value < float("inf"):
            raise InputError(f"--{option.replace('_', '-')}: must be a positive number of seconds, got {value}")
    check_output_path("--log", args.log)
    controller = CreepController(load_calibration(args.calibration))
    config = bus_config(args)
    db = load_dbc(args.dbc)
    codec = Codec(db, TCU_USES)
    faults = check_faults(faults_from_args(args), db)
    if faults["plant"]:
        raise FaultError(f"{faults['plant'][0].origin}: changes the plant's frames: give it to dsg-hil, or "
                         f"side=tcu")
    inner = open_bus(config, receive=[db.get_message_by_name(name) for name in TCU_RX])
    tcu_side: list[TcuRunner] = []  # the fault clock reads the TCU's time
    bus, injector = with_faults(inner, db, faults["tcu"], args.fault_seed, lambda: tcu_side[0].now)
    record = FrameLog(args.log, log_channel(config)) if args.log else None
    tcu = TcuRunner(codec, bus, controller, (record,) if record else ())
    tcu_side.append(tcu)
    try:  # 'listening' inside: a signal from then on still reaches the counts below
        print(f"ecu-stub: listening on {bus_name(config)}", file=sys.stderr, flush=True)
        if warning := per_process_warning(config):
            print(f"ecu-stub: warning: {warning}", file=sys.stderr, flush=True)
        tcu.run(duration=args.duration, idle_timeout=args.idle_exit, should_stop=stop.is_set)
    finally:
        bus.shutdown()
        if record is not None:
            record.stop()
        c = tcu.frame_counts()
        print(f"ecu-stub: sent {c['sent']} frames ({c['answers_resent']} lock-step answers re-sent, "
              f"{c['incomplete_answers']} on incomplete plant frames); received "
              f"{c['received']}, rejected {c['rejected']}{by_cause(tcu.rx.rejected)}, lost {c['lost']}, "
              f"duplicates {c['duplicates']}", file=sys.stderr, flush=True)
        if injector is not None:
            print(f"ecu-stub: faults injected (frames hit): {injector.hits()}", file=sys.stderr, flush=True)
