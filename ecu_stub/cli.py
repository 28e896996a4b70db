"""``ecu-stub`` (also ``python -m ecu_stub``): the TCU process on a CAN bus.

Exit status as dsg-hil's (:func:`dsg_hil.common.cli.run_main`): 0 at ``--duration`` or ``--idle-exit``, 1 the run
failed, 2 bad input or usage (one ``error:`` line naming the file or option), 130 Ctrl-C, 143 SIGTERM (serving
stops, the frame counts are printed), at any moment from the first line of :func:`main`: this module imports the
standard library and ``dsg_hil.common`` only, python-can and the rest once main's signal handling is in place.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
from collections.abc import Mapping
from contextlib import ExitStack
from importlib import metadata
from pathlib import Path
from typing import Any

from dsg_hil.common.cli import run_main, signals_held
from dsg_hil.common.errors import InputError
from dsg_hil.common.files import check_output_path

__all__ = ["EXAMPLE_FAULTS", "XCP_IDS", "by_cause", "main", "version", "xcp_ids"]

EXAMPLE_FAULTS = ("drop:TCU_CMD@10-12", "stuck:TCU_STATUS.T_CL_Pred@5-8,value=20")  # --help: the TCU's own frames
XCP_IDS = (0x7D0, 0x7D1)  # --xcp-ids default: CRO, DTO (ecu_stub.xcp.DEFAULT_IDS; not imported for --help)


def version() -> str:
    """The version of the dsg-hil distribution that ships ecu-stub (dsg_hil.__version__, through its metadata)."""
    try:
        return metadata.version("dsg-hil")
    except metadata.PackageNotFoundError:
        return "(dsg-hil not installed)"


def xcp_ids(text: str) -> tuple[int, int]:
    """``--xcp-ids``: 'CRO,DTO', two different 11-bit CAN IDs (decimal or 0x hex); else a usage error."""
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"give two CAN IDs as CRO,DTO (e.g. 0x7D0,0x7D1), got {text!r}")
    ids = []
    for part in parts:
        try:
            value = int(part.strip(), 0)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {part!r} (decimal or 0x hex)") from None
        if not 0 <= value <= 0x7FF:
            raise argparse.ArgumentTypeError(f"an 11-bit CAN ID must be 0x0-0x7FF, got {part.strip()}")
        ids.append(value)
    if ids[0] == ids[1]:
        raise argparse.ArgumentTypeError(f"CRO and DTO must differ, got {text}")
    return ids[0], ids[1]


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    from dsg_hil.protocol.bus import add_bus_arguments  # noqa: PLC0415 - python-can: after main's signal handling
    from dsg_hil.protocol.faults import add_fault_arguments  # noqa: PLC0415

    parser = argparse.ArgumentParser(
        prog="ecu-stub",
        description="Transmission control unit with the paper's creep strategy: engages CL first (hill-hold and "
                    "pre-fill), tracks the desired creep speed with clutch pressure, predicts both plate temperatures "
                    "with its calibrated model, hands the torque over to the other clutch before the slipping one can "
                    "pass 250 degC, and stops the vehicle when neither can take over. Knows the plant only through "
                    "the DBC and its binding (--dbc, --binding). Answers the lock-step ticks when the plant runs in "
                    "lockstep, else runs on its own clock at the command message's cycle time.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    add_bus_arguments(parser, fresh_udp=False)
    parser.add_argument("--dbc", metavar="FILE",
                        help="the communication matrix, a DBC or an ARXML (default: the DBC shipped with dsg-hil)")
    parser.add_argument("--binding", metavar="FILE",
                        help="the binding TOML that says which of the matrix's signals carry each quantity, as "
                             "dsg-hil takes it (default: the shipped one, of the shipped DBC; check a pair with "
                             "dsg-hil binding check)")
    parser.add_argument("--calibration", metavar="FILE",
                        help="TCU calibration TOML (default: ecu_stub/data/calibration.toml)")
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: never)")
    add_fault_arguments(parser, "the frames the TCU sends", EXAMPLE_FAULTS)
    parser.add_argument("--log", metavar="FILE",
                        help="record the frames the TCU took and sent (first transmissions; lockstep: stamped "
                             "with simulated time), in python-can's format for the extension: .log (candump -L), "
                             ".asc, .blf, .csv ...")
    parser.add_argument("--xcp", action="store_true",
                        help="serve XCP on CAN as well (ASAM MCD-1 XCP: measure the TCU's internals by DAQ each "
                             "control period, change calibration values at run time; the A2L: --a2l)")
    parser.add_argument("--xcp-ids", type=xcp_ids, metavar="CRO,DTO",
                        help="the XCP master's and the TCU's CAN IDs (default: 0x7D0,0x7D1); neither may be "
                             "a DBC message's or a diagnostic ID")
    parser.add_argument("--a2l", metavar="FILE",
                        help="write the A2L file of the XCP slave (its calibration values, measurements, DAQ "
                             "event and CAN IDs) and exit")
    parser.add_argument("--idle-exit", type=float, metavar="S",
                        help="stop when the plant has been silent for S seconds after having been heard")
    loudness = parser.add_mutually_exclusive_group()  # as dsg-hil's -v/-q
    loudness.add_argument("-v", "--verbose", action="store_true", help="log protocol events")
    loudness.add_argument("-q", "--quiet", action="store_true",
                          help="print errors only, and the frame counts at the end (they count what the warnings "
                               "would have said: frames rejected, lost, answers re-sent): no 'listening' line, no "
                               "warnings")
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
    if args.a2l is not None:
        _write_a2l(args)
        return
    with ExitStack() as stack:
        with signals_held():  # set up whole (imports, DBC, bus, log): a signal now acts once the TCU is ready
            tcu, config = _set_up(args, stack)
        from dsg_hil.protocol.bus import bus_name, per_process_warning  # noqa: PLC0415 - loaded by _set_up

        if not args.quiet:
            print(f"ecu-stub: listening on {bus_name(config)}", file=sys.stderr, flush=True)
            if warning := per_process_warning(config):
                print(f"ecu-stub: warning: {warning}", file=sys.stderr, flush=True)
            if tcu.xcp is not None:
                cro, dto = tcu.xcp.request_id, tcu.xcp.response_id
                print(f"ecu-stub: XCP slave on CAN, master 0x{cro:X}, slave 0x{dto:X}", file=sys.stderr, flush=True)
        tcu.run(duration=args.duration, idle_timeout=args.idle_exit, should_stop=stop.is_set)


def _checked_xcp_ids(args: argparse.Namespace, db: Any) -> tuple[int, int]:
    """--xcp-ids (or the default), checked against the DBC's messages and diagnostic IDs."""
    from dsg_hil.protocol.diag import diag_ids  # noqa: PLC0415

    ids = args.xcp_ids or XCP_IDS
    taken = {m.frame_id: f"the ID of {m.name} in the DBC" for m in db.messages}
    if db.dbc is not None and "DiagRequestId" in db.dbc.attributes:
        request, response = diag_ids(db)
        taken.update({request: "the DBC's diagnostic request ID", response: "the DBC's diagnostic response ID"})
    option = "--xcp-ids" + (f" 0x{ids[0]:X},0x{ids[1]:X}" if args.xcp_ids else f" (default 0x{ids[0]:X},0x{ids[1]:X})")
    for frame_id in ids:
        if frame_id in taken:
            raise InputError(f"{option}: 0x{frame_id:X} is {taken[frame_id]}")
    return ids


def _write_a2l(args: argparse.Namespace) -> None:
    """--a2l FILE: the A2L of the slave on the checked IDs, written whole (nothing written on bad input)."""
    from dsg_hil.protocol import load_dbc  # noqa: PLC0415

    from .xcp.a2l import a2l_text  # noqa: PLC0415

    check_output_path("--a2l", args.a2l)
    cro, dto = _checked_xcp_ids(args, load_dbc(args.dbc))
    path = Path(args.a2l)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(a2l_text(cro, dto, version(), path.stem if path.stem.isidentifier() else "ecu_stub"),
                    encoding="latin-1")


def _set_up(args: argparse.Namespace, stack: ExitStack) -> tuple[Any, dict[str, Any]]:
    """The TCU on its bus, the bus and log closed and the counts printed when ``stack`` closes (however
    serving ends); returns it and the bus configuration."""
    from dsg_hil.protocol import load_dbc  # noqa: PLC0415 - cantools when serving, not for --help
    from dsg_hil.protocol.binding import BindingError, load_binding  # noqa: PLC0415
    from dsg_hil.protocol.bus import (  # noqa: PLC0415
        FrameLog, bus_config, has_fd, log_channel, open_bus, receive_filters)
    from dsg_hil.protocol.diag import diag_ids  # noqa: PLC0415
    from dsg_hil.protocol.faults import FaultError, check_faults, faults_from_args, with_faults  # noqa: PLC0415

    from .calibration import load_calibration  # noqa: PLC0415
    from .controller import CreepController  # noqa: PLC0415
    from .runner import TcuRunner  # noqa: PLC0415
    from .tcu_io import TcuIO  # noqa: PLC0415

    level = logging.INFO if args.verbose else logging.ERROR if args.quiet else logging.WARNING
    logging.basicConfig(level=level, stream=sys.stderr, format="%(levelname)s %(name)s: %(message)s")
    for option in ("duration", "idle_exit"):
        value = getattr(args, option)
        if value is not None and not 0.0 < value < float("inf"):
            raise InputError(f"--{option.replace('_', '-')}: must be a positive number of seconds, got {value}")
    check_output_path("--log", args.log)
    if args.xcp_ids is not None and not args.xcp:
        raise InputError("--xcp-ids: serves nothing without --xcp (or --a2l)")
    calibration = load_calibration(args.calibration)
    config = bus_config(args)
    db = load_dbc(args.dbc)  # a DBC that cannot be read: ProtocolError naming it and what is wrong, alone
    try:  # the pair checked together: BindingError naming the file
        binding = load_binding(args.binding, db=db)
    except BindingError as exc:
        if args.binding is not None or args.dbc is None:
            raise
        raise BindingError(f"{args.dbc}: does not fit the shipped binding: give its own (--binding); {exc}") from None
    db, io = binding.db, TcuIO(binding)
    controller = CreepController(calibration, io.matrix_steps)  # (the plausibility checks' steps: the matrix's)
    codec = io.codec(db)
    xcp = _checked_xcp_ids(args, db) if args.xcp else None
    faults = check_faults(faults_from_args(args), db, binding.sides)  # (a side by the binding, as dsg-hil run's)
    if faults["plant"]:
        raise FaultError(f"{faults['plant'][0].origin}: changes the plant's frames: give it to dsg-hil, or "
                         f"side=tcu")
    inner = open_bus(config, receive=[db.get_message_by_name(name) for name in io.rx], fd=has_fd(db.messages))
    requests = [diag_ids(db)[0]] if db.dbc is not None and "DiagRequestId" in db.dbc.attributes else []
    requests += [xcp[0]] if xcp is not None else []
    if requests:  # and UDS requests (ecu_stub.diag), XCP commands (ecu_stub.xcp)
        filters: list[Any] = [*receive_filters(db.get_message_by_name(name) for name in io.rx)]
        filters += [{"can_id": i, "can_mask": 0x7FF, "extended": False} for i in requests]
        inner.set_filters(filters)
    tcu_side: list[TcuRunner] = []  # the fault clock reads the TCU's time
    bus, injector = with_faults(inner, db, faults["tcu"], args.fault_seed, lambda: tcu_side[0].now)
    stack.callback(bus.shutdown)
    record = FrameLog(args.log, log_channel(config)) if args.log else None
    if record is not None:
        stack.callback(record.stop)
    slave = None
    if xcp is not None:
        from .xcp import xcp_slave  # noqa: PLC0415

        slave = xcp_slave(*xcp)
    tcu = TcuRunner(codec, bus, controller, (record,) if record else (), slave, io)
    tcu_side.append(tcu)
    stack.callback(_print_counts, tcu, injector)  # first when the stack closes, then the log and the bus
    return tcu, config


def _print_counts(tcu: Any, injector: Any) -> None:
    c = tcu.frame_counts()
    print(f"ecu-stub: sent {c['sent']} frames ({c['answers_resent']} lock-step answers re-sent, "
          f"{c['incomplete_answers']} on incomplete plant frames, {c['ticks_missed']} ticks never seen); received "
          f"{c['received']}, rejected {c['rejected']}{by_cause(tcu.rx.rejected)}, lost {c['lost']}, "
          f"duplicates {c['duplicates']}", file=sys.stderr, flush=True)
    if injector is not None:
        print(f"ecu-stub: faults injected (frames hit): {injector.hits()}", file=sys.stderr, flush=True)
