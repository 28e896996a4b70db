"""Test a controller against the plant: one call, :func:`run_plant`, runs a scenario in lockstep and gives the
summary, every decoded signal as a time series, the plant's truth each control period, and the log.

The controller is one of

* ``None``: the bundled ecu-stub, in this process (python-can ``virtual``); or an ecu-stub
  :class:`~ecu_stub.controller.CreepController` (e.g. with another calibration);
* a command line (``list`` of ``str``, or :class:`ControllerProcess`): started as a process on a
  ``udp_multicast`` group and port of the run's own (a compiled ECU, a script, ``ecu-stub`` itself);
* a Python object with ``step(t, inputs)`` (:class:`Controller`), run in this process.

The pytest plugin (:mod:`dsg_hil.testing.plugin`, fixture ``dsg_hil_run``) calls this with a directory per run.
"""

from __future__ import annotations

import dataclasses
import subprocess
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, TypeGuard

import can
import numpy as np
from cantools.database.can import Database

from ..common.errors import InputError
from ..sim.loop import at_each_tick, plant_for, run_closed_loop
from ..physics.params import Params, load_params
from ..physics.plant import PlantOutputs
from ..sim.plant_io import PLANT_USES
from ..protocol import Codec, load_dbc
from ..protocol.bus import LOG_CHANNEL, UDP_MULTICAST, bus_name, fresh_udp_group, open_bus
from ..protocol.faults import FaultSpec, check_faults, parse_fault
from ..sim.runner import PeerTimeout, PlantRunner
from ..sim.scenario import Scenario, load_scenario
from .controllers import Controller, ControllerProcess, PythonControllerTcu
from .signals import Signals, decode_frames

__all__ = ["PlantRun", "run_plant"]

ControllerLike = Controller | ControllerProcess | Sequence[str] | Any  # or None: the bundled ecu-stub


@dataclass
class PlantRun:
    """What a run gives.

    ``summary``: as ``dsg-hil run --summary`` writes it (``dsg_hil/summary.py``). ``signals``: every frame on the
    bus (the plant's as it sent them, the controller's as the plant accepted them) decoded, see :class:`Signals`.
    ``truth``: the plant once per control period, at the tick's time, unquantised: ``truth["t"]`` [s] and each
    field of :class:`~dsg_hil.physics.plant.PlantOutputs` (SI: rad/s, Pa, N m, W; temperatures degC), e.g.
    ``truth["T_CL"]``, ``truth["v"]``. ``frames``: the frames themselves. ``log``: the log file (None if not
    asked for). ``controller_output``: the controller process's stdout and stderr (process controllers)."""

    summary: dict[str, Any]
    signals: Signals
    truth: dict[str, np.ndarray]
    frames: list[can.Message]
    log: Path | None
    controller_output: Path | None = None


def run_plant(controller: ControllerLike = None, *, scenario: Scenario | str | Path | None = None,
              duration: float | None = None, params: Params | str | Path | Mapping[str, float] | None = None,
              faults: Iterable[FaultSpec | str] | None = None, fault_seed: int = 0,
              out_dir: str | Path | None = None, log: str | None = "run.asc", reply_timeout: float = 5.0,
              startup_timeout: float = 60.0) -> PlantRun:
    """Run ``scenario`` (default: the shipped creep scenario; a path to a scenario TOML or a
    :class:`~dsg_hil.sim.scenario.Scenario`) for ``duration`` s (default: the scenario's) with ``controller`` in
    lockstep.

    ``params``: a parameter file, a :class:`~dsg_hil.physics.params.Params`, or overrides of the shipped
    parameters by dotted key (``{"vehicle.m": 1900.0}``, SI units as in ``dsg-hil params``). ``faults``: fault
    specs or ``--fault`` strings (``"drop:TCU_CMD@2-2.1"``), default the scenario's ``[[fault]]`` tables; a
    process controller takes plant-side faults only (give it its own). ``out_dir``: where the log
    (``log``, by extension: ``.asc``, ``.blf``, ``.log`` ..., None for none) and the controller process's
    output go (needed for a log). Raises :class:`~dsg_hil.sim.runner.PeerTimeout` when the controller never answers
    the presence probe, :class:`~dsg_hil.sim.runner.PeerLost` when it falls silent for ``reply_timeout`` s."""
    scenario = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if duration is not None:
        scenario = scenario.with_duration(duration)
    params = _params(params)
    specs = [parse_fault(f) if isinstance(f, str) else f for f in (scenario.faults if faults is None else faults)]
    out = Path(out_dir) if out_dir is not None else None
    if log is not None and out is None:
        raise InputError("run_plant: log needs out_dir (the directory to write it into)")
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    db = load_dbc()
    truth: list[tuple[float, PlantOutputs]] = []

    def record(runner: PlantRunner) -> None:
        truth.append((runner.tick * runner.period, runner.out))

    output = None
    if isinstance(controller, ControllerProcess) or _is_command(controller):
        process = controller if isinstance(controller, ControllerProcess) else ControllerProcess(list(controller))
        output = (out / "controller.out") if out is not None else None
        summary, frames = _run_process(process, scenario, params, db, specs, fault_seed, record, output,
                                       reply_timeout, startup_timeout)
    else:
        result = run_closed_loop(scenario, params, db=db, tcu_factory=_tcu_factory(controller), capture=True,
                                 faults=specs, fault_seed=fault_seed, on_period=record)
        summary, frames = result.summary, result.frames
    log_path = _write_log(out / log, frames) if out is not None and log is not None else None
    return PlantRun(summary, decode_frames(db, frames), _truth_arrays(truth), frames, log_path, output)


def _params(params: Params | str | Path | Mapping[str, float] | None) -> Params:
    if isinstance(params, Params):
        return params
    if isinstance(params, Mapping):
        base = load_params()
        for key, value in params.items():
            base = _replace_dotted(base, key.split("."), value, key)
        return base
    return load_params(params)


def _replace_dotted(obj: Any, path: list[str], value: float, key: str) -> Any:
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type) or not hasattr(obj, path[0]):
        raise InputError(f"params: no parameter {key!r} (see 'dsg-hil params' for the keys)")
    inner = value if len(path) == 1 else _replace_dotted(getattr(obj, path[0]), path[1:], value, key)
    return dataclasses.replace(obj, **{path[0]: inner})


def _is_command(controller: Any) -> TypeGuard[Sequence[str]]:
    return isinstance(controller, (list, tuple)) and bool(controller) and all(isinstance(a, str) for a in controller)


def _tcu_factory(controller: Any) -> Callable[[Database, can.BusABC], Any] | None:
    """How run_closed_loop builds the in-process TCU: ecu-stub (``None`` or its controller) or a Controller."""
    if controller is None:
        return None
    from ecu_stub.controller import CreepController
    from ecu_stub.runner import TCU_USES, TcuRunner

    if isinstance(controller, CreepController):
        return lambda db, bus: TcuRunner(Codec(db, TCU_USES), bus, controller)
    if isinstance(controller, Controller):
        return lambda db, bus: PythonControllerTcu(Codec(db, TCU_USES), bus, controller)
    raise TypeError(f"controller: expected None, an ecu-stub CreepController, a command line (list of str), a "
                    f"ControllerProcess or an object with step(t, inputs); got {type(controller).__name__}")


def _run_process(process: ControllerProcess, scenario: Scenario, params: Params, db: Database,
                 specs: list[FaultSpec], fault_seed: int, record: Callable[[PlantRunner], None],
                 output: Path | None, reply_timeout: float,
                 startup_timeout: float) -> tuple[dict[str, Any], list[can.Message]]:
    """The plant on a fresh udp_multicast group, the controller as a process on it, lockstep."""
    by_side = check_faults(specs, db)
    if by_side["tcu"]:
        raise InputError(f"{by_side['tcu'][0].origin}: changes the controller's frames: a controller process "
                         "injects its own (ecu-stub: --fault)")
    config = {"interface": UDP_MULTICAST, **fresh_udp_group()}
    frames: list[can.Message] = []
    bus = open_bus(config)
    runner = PlantRunner(plant_for(scenario, params), scenario, Codec(db, PLANT_USES), bus,
                         (frames.append, at_each_tick(db, lambda: record(runner))))
    with (open(output, "w+b") if output is not None else tempfile.TemporaryFile()) as sink:
        try:
            runner.inject(by_side["plant"], fault_seed)
            proc = process.start(config, sink)
            try:
                summary = runner.run_lockstep(reply_timeout, startup_timeout=startup_timeout)
            except PeerTimeout as exc:
                raise type(exc)(f"{exc} (controller {process.command(config)}: "
                                f"{_process_state(proc, sink)})") from None
            finally:
                process.stop(proc)
        finally:
            runner.bus.shutdown()
            if runner.bus is not bus:
                bus.shutdown()
    data = summary.as_json(runner.frames(), scenario.name, "lockstep", bus_name(config), scenario.duration_s)
    data["faults"] = runner.fault_summary()
    return data, frames


def _process_state(proc: subprocess.Popen[bytes], sink: IO[bytes]) -> str:
    status = proc.poll()
    sink.flush()
    sink.seek(0)
    tail = sink.read()[-2000:].decode(errors="replace").strip()
    state = "still running" if status is None else f"exited with status {status}"
    return f"{state}; its output: {tail or '(none)'}"


def _truth_arrays(truth: list[tuple[float, PlantOutputs]]) -> dict[str, np.ndarray]:
    arrays = {"t": np.array([t for t, _ in truth], dtype=float)}
    for i, name in enumerate(PlantOutputs._fields):
        arrays[name] = np.array([out[i] for _, out in truth])
    return arrays


def _write_log(path: Path, frames: list[can.Message]) -> Path:
    """The frames through python-can's writer for the file's extension, on channel vcan0 (as dsg-hil's logs)."""
    try:
        writer = can.Logger(str(path))
    except ValueError as exc:
        raise InputError(f"log {path.name}: {exc}") from None
    try:
        for msg in frames:
            writer.on_message_received(can.Message(timestamp=msg.timestamp, arbitration_id=msg.arbitration_id,
                                                   data=msg.data, is_extended_id=msg.is_extended_id,
                                                   channel=LOG_CHANNEL, is_rx=msg.is_rx))
    finally:
        writer.stop()
    return path
