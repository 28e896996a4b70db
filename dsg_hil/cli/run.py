"""``dsg-hil run``: the plant and the TCU together, and a summary of what happened."""

from __future__ import annotations

import argparse
import subprocess
import sys
import threading
import time
from contextlib import ExitStack
from typing import TYPE_CHECKING, Any

from ..common.errors import RunError
from ..protocol.bus import bus_args, open_bus
from . import command_help
from .busopts import add_bus_options, drive, finish, frames_line, start
from .common import add_params_option, progress

if TYPE_CHECKING:
    from cantools.database.can import Database

    from ..sim.runner import PlantRunner


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
    parser.set_defaults(func=_do_run, tcu_in_process=True)


def _tcu_in_process(bus_config: dict, dbc: Database, runner: PlantRunner, args: argparse.Namespace) -> Any:
    """The TCU side in this process (virtual bus only: the in-process bus's other end where there is one), its
    frames through the TCU-side faults."""
    from ..sim.loop import attach_tcu  # noqa: PLC0415 - the TCU (cantools ...) when a run starts

    bus = getattr(args, "tcu_bus", None) or open_bus(bus_config)
    tcu, _ = attach_tcu(runner, bus, dbc, args.faults_by_side["tcu"], getattr(args, "fault_seed", 0))
    return tcu


def _do_run(args: argparse.Namespace) -> int:
    from ..sim.loop import answer_at_once  # noqa: PLC0415 - the plant (numpy ...) when a run starts

    with ExitStack() as stack:
        runner, config, scenario = start(args, stack, "run")
        t0 = time.monotonic()
        if config["interface"] == "virtual":
            tcu = _tcu_in_process(config, runner.codec.db, runner, args)
            stack.callback(tcu.bus.shutdown)
            if args.mode == "lockstep":
                answer_at_once(runner)
                drive(runner, args, pump=tcu.pump)
            else:
                errors: list[BaseException] = []
                done = threading.Event()

                def serve() -> None:
                    try:
                        tcu.run(should_stop=done.is_set)
                    except BaseException as exc:  # noqa: BLE001 - re-raised in the main thread
                        errors.append(exc)

                thread = threading.Thread(target=serve, name="ecu-stub", daemon=True)
                thread.start()
                try:
                    runner.run_realtime()
                finally:
                    done.set()
                    thread.join()
                if errors:
                    raise errors[0]
        else:
            faults = [arg for spec in args.faults_by_side["tcu"] for arg in ("--fault", spec.as_option())]
            if faults:
                faults += ["--fault-seed", str(args.fault_seed)]
                progress("faults on the TCU's frames: passed to ecu-stub, which counts them (see its output)")
                runner.faults_in_tcu = [spec.describe() for spec in args.faults_by_side["tcu"]]
            # the TCU waits for a silent plant as long as the plant waits for a silent TCU (--reply-timeout);
            # at the end of the run it is stopped by the plant, so this only ends a TCU whose plant died
            idle = f"{max(args.reply_timeout, 2.0):g}"
            cmd = [sys.executable, "-m", "ecu_stub", *bus_args(config), "--idle-exit", idle, *faults]
            tcu_proc = subprocess.Popen(cmd)
            stack.callback(_stop_process, tcu_proc)
            time.sleep(0.5)
            if tcu_proc.poll() is not None:
                raise RunError(f"ecu-stub exited at start (status {tcu_proc.returncode})")
            drive(runner, args)
        wall = time.monotonic() - t0
        summary = finish(args, runner, config, scenario)
    progress(f"done: {scenario.duration_s:g} simulated s in {wall:.1f} s wall; stop: {summary['stop_reason']}; "
             f"handovers: {len(summary['handovers'])}; {frames_line(summary['frames'])}")
    return 0


def _stop_process(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
