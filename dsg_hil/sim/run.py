"""One way to set up and run a simulation: :class:`RunConfig` says what to run, :func:`open_run` builds it (plant,
bus, log, faults, TCU) and :meth:`Run.run` runs it; the summary is finished here and nowhere else.

Every entry point is built on this: ``dsg-hil run``, ``dsg-hil plant``, ``dsg-hil report``,
:func:`dsg_hil.sim.loop.run_closed_loop`, :func:`dsg_hil.testing.run_plant` and the pytest fixture::

    from dsg_hil.sim.run import RunConfig, open_run

    config = RunConfig(scenario="my_creep.toml", duration=60.0, log="run.asc", summary="summary.json")
    with open_run(config) as run:
        summary = run.run()
    print(summary.stop_reason, summary.max_plate_temp_c)

The run's resources (buses, log, a TCU process) are closed when the ``with`` block ends, and the summary file is
written however the run ends: at its end, on Ctrl-C, SIGTERM (:class:`~dsg_hil.common.cli.Terminated`), or a lost
TCU, with the stop reason ``interrupted``, ``terminated``, ``peer_lost`` or ``no_peer``; and if a signal comes
before the run is set up, :func:`unstarted_summary` writes that of zero periods (``dsg-hil run``/``plant`` do).
"""

from __future__ import annotations

import gc
import inspect
import itertools
import json
import os
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from types import TracebackType
from typing import IO, Any, Literal, Protocol, cast, runtime_checkable

import can
import numpy as np
from cantools.database.can import Database

from ..common.errors import InputError, RunError
from ..common.files import check_output_path
from ..physics.params import Params, load_params, with_overrides
from ..physics.plant import PlantOutputs
from ..protocol import Codec, load_dbc
from ..protocol.binding import Binding, load_binding
from ..protocol.codec import ProtocolError
from ..protocol.bus import FrameLog, bus_args, bus_name, has_fd, log_channel, open_bus
from ..protocol.frame import FrameListener
from ..protocol.faults import FaultError, FaultSpec, check_faults, parse_fault, with_faults
from ..protocol.local import local_pair
from ..protocol.lockstep import answers_lost_by
from ..results.outcome import Summary
from ..results.summary import RunSummary
from ..physics.thermal import NODES
from ..physics.plant import Plant
from .operating_range import outside_range
from .plant_io import SHIPPED, PlantIO, from_binding
from .runner import PeerLost, PeerTimeout, PlantRunner
from .scenario import Scenario, load_scenario

__all__ = ["ECU_STUB", "EcuStubProcess", "Run", "RunConfig", "TcuFactory", "TcuProcess", "answer_at_once",
           "attach_tcu", "open_run", "plant_for", "private_channel", "stop_process",
           "unstarted_summary"]

ECU_STUB = "ecu-stub"  # RunConfig.tcu: the bundled TCU, in this process where the bus allows, else as a process
Mode = Literal["lockstep", "realtime"]
# (db, bus) -> an object with pump(), now, run(...), bus; one with a parameter io also gets the TCU's I/O on a
# binding's matrix (an ecu_stub.tcu_io.TcuIO: Run._check_tcu_factory)
TcuFactory = Callable[[Database, can.BusABC], Any]
_channels = itertools.count()


@runtime_checkable
class TcuProcess(Protocol):
    """A TCU started as a process on the run's bus (:class:`EcuStubProcess`,
    :class:`dsg_hil.testing.ControllerProcess`)."""

    def command(self, config: Mapping[str, Any]) -> list[str]: ...

    def start(self, config: Mapping[str, Any], output: IO[bytes]) -> subprocess.Popen[bytes]: ...

    def stop(self, proc: subprocess.Popen[bytes]) -> None: ...


@dataclass(frozen=True)
class EcuStubProcess:
    """The bundled TCU as a process (``python -m ecu_stub`` with the run's bus options), its output on this
    process's (``inherit_output``). ``faults``: ``--fault`` options for the TCU's own frames (it counts them);
    ``idle_exit``: it ends once the plant is silent this long (so a TCU whose plant died does not linger)."""

    faults: tuple[FaultSpec, ...] = ()
    fault_seed: int = 0
    calibration: str | None = None  # its calibration TOML (--calibration; None: the shipped one)
    dbc: str | None = None  # the matrix and its binding (--dbc, --binding; None: the shipped ones)
    binding: str | None = None
    idle_exit: float = 5.0
    quiet: bool = False  # errors and its closing counts only (ecu-stub --quiet)
    inherit_output: bool = True
    stop_timeout: float = 5.0

    def command(self, config: Mapping[str, Any]) -> list[str]:
        faults = [arg for spec in self.faults for arg in ("--fault", spec.as_option())]
        if faults:
            faults += ["--fault-seed", str(self.fault_seed)]
        calibration = [] if self.calibration is None else ["--calibration", self.calibration]
        calibration += [arg for option, path in (("--dbc", self.dbc), ("--binding", self.binding)) if path is not None
                        for arg in (option, path)]
        quiet = ["--quiet"] if self.quiet else []
        return [sys.executable, "-m", "ecu_stub", *bus_args(dict(config)), "--idle-exit", f"{self.idle_exit:g}",
                *calibration, *faults, *quiet]

    def start(self, config: Mapping[str, Any], output: IO[bytes]) -> subprocess.Popen[bytes]:
        sink = None if self.inherit_output else output
        return subprocess.Popen(self.command(config), stdout=sink, stderr=None if sink is None else subprocess.STDOUT)

    def stop(self, proc: subprocess.Popen[bytes]) -> None:
        stop_process(proc, self.stop_timeout)


def stop_process(proc: subprocess.Popen[bytes], timeout: float) -> None:
    """End a TCU process: SIGTERM, then SIGKILL after ``timeout`` seconds."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@dataclass(frozen=True)
class RunConfig:
    """What to run. Every field has a default: ``RunConfig()`` is the shipped creep scenario against the bundled
    TCU in lockstep on a direct in-process bus.

    * ``scenario``: a :class:`~dsg_hil.sim.scenario.Scenario` or a scenario TOML (None: the shipped one);
      ``duration`` [s] overrides its duration.
    * ``params``: a :class:`~dsg_hil.physics.params.Params`, a parameter TOML, or overrides of the shipped
      parameters by dotted key (``{"vehicle.m": 1900.0}``, SI as ``dsg-hil params`` lists them).
    * ``dbc``: a DBC file or a loaded cantools database (None: the shipped one). ``binding``: the binding file
      that says which of its signals carry the plant's quantities (:mod:`dsg_hil.protocol.binding`; None: the
      shipped DBC's), checked against the DBC at start; its cycle times overridden in the database.
    * ``mode``: ``lockstep`` (the plant is the time master; bit-for-bit reproducible) or ``realtime``.
    * ``bus``: a python-can configuration (``{"interface": "socketcan", "channel": "vcan0"}``); None: a direct
      in-process bus (:mod:`dsg_hil.protocol.local`). ``direct``: an in-process TCU in lockstep on python-can's
      ``virtual`` interface talks over the direct bus instead (the same frames, faster).
    * ``tcu``: :data:`ECU_STUB` (the bundled TCU: in this process on a direct or ``virtual`` bus, else started
      as a process), a factory ``(db, bus) -> TCU`` for a TCU object in this process (``(db, bus, io)``: also on a
      binding's matrix, ``io`` its ``ecu_stub.tcu_io.TcuIO``; one without ``io`` there is an error), a
      :class:`TcuProcess`,
      or None (none: a TCU runs elsewhere, as for ``dsg-hil plant``). ``calibration``: the bundled TCU's
      calibration TOML (None: the shipped one; ``python -m ecu_stub.identify --write`` makes one), checked at start.
    * ``faults``: fault specs or ``--fault`` strings (None: the scenario's ``[[fault]]`` tables), each on the
      side whose frames it changes, drawn from generators seeded ``fault_seed``.
    * ``log``: record the bus traffic to this file (by extension: ``.log`` candump -L, ``.asc``, ``.blf`` ...);
      ``summary``: write the JSON summary here however the run ends; ``tcu_output``: a TCU process's output.
    * ``capture``: keep every frame in :attr:`Run.frames`; ``truth``: keep the plant's outputs each control period
      (:meth:`Run.truth`); ``listeners`` get every frame the plant sent or took; ``on_period(runner)`` is called
      once per control period, as the plant sends the period's SIM_SYNC tick.
    * ``reply_timeout``/``startup_timeout`` [s of wall time]: lockstep waits for a silent TCU, and for the first
      answer to the presence probe. ``progress``: a callable for progress lines (None: quiet). ``quiet``: the
      bundled TCU, when started as a process, prints errors and its closing counts only (``ecu-stub --quiet``).
    * ``reference_codec``: encode and decode through cantools instead of the generated codec (the same frames,
      slower: a benchmark's baseline).
    """

    scenario: Scenario | str | Path | None = None
    duration: float | None = None
    params: Params | str | Path | Mapping[str, float] | None = None
    dbc: Database | str | Path | None = None
    binding: str | Path | None = None
    mode: Mode = "lockstep"
    bus: Mapping[str, Any] | None = None
    direct: bool = True
    tcu: str | TcuFactory | TcuProcess | None = ECU_STUB
    calibration: str | Path | None = None
    faults: Sequence[FaultSpec | str] | None = None
    fault_seed: int = 0
    log: str | Path | None = None
    summary: str | Path | None = None
    tcu_output: str | Path | None = None
    capture: bool = False
    truth: bool = False
    listeners: Sequence[FrameListener] = ()
    on_period: Callable[[PlantRunner], None] | None = None
    reply_timeout: float = 5.0
    startup_timeout: float = 60.0
    progress: Callable[[str], None] | None = None
    quiet: bool = False
    reference_codec: bool = False


def resolve_scenario(scenario: Scenario | str | Path | None, duration: float | None = None) -> Scenario:
    """The scenario of a :class:`RunConfig`, its duration overridden if given."""
    resolved = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    return resolved if duration is None else resolved.with_duration(duration)


def resolve_params(params: Params | str | Path | Mapping[str, float] | None) -> Params:
    """The parameters of a :class:`RunConfig`."""
    if isinstance(params, Params):
        return params
    if isinstance(params, Mapping):
        return with_overrides(load_params(), params)
    return load_params(params)


class Run:
    """A run set up by :func:`open_run`: the plant runner (``runner``; its plant holds the truth), the TCU if it
    runs in this process (``tcu``), the frames if captured (``frames``). A context manager: leaving it closes
    the run's resources and writes the summary file."""

    def __init__(self, config: RunConfig, stack: ExitStack) -> None:
        self.config = config
        self._stack = stack
        self.scenario = resolve_scenario(config.scenario, config.duration)
        self.params = resolve_params(config.params)
        self.db = config.dbc if isinstance(config.dbc, Database) else load_dbc(config.dbc)
        self.io, self._protection, self._timeouts = self._binding()
        codec = self._plant_codec()
        self.frames: list[can.Message] = []
        self._truth: list[tuple[float, PlantOutputs]] = []
        self.tcu: Any = None
        specs = [parse_fault(f) if isinstance(f, str) else f
                 for f in (self.scenario.faults if config.faults is None else config.faults)]
        self.faults_by_side = check_faults(specs, self.db, self.binding.sides if self.binding is not None else None)
        self.calibration = self._calibration()
        self.bus_config, direct = self._bus_config()
        self.interface = bus_name(self.bus_config)
        process = self._tcu_process()
        self._check_bundled_tcu()
        self._check_tcu_factory()
        self._check_paths()
        # nothing was opened or written up to here: bad input fails before this line
        plant_bus, tcu_bus = self._open_buses(direct)
        listeners = self._listeners()
        self.runner = PlantRunner(plant_for(self.scenario, self.params), self.scenario, codec, plant_bus,
                                  listeners, config.progress, self.io)
        self.runner.link.notify = config.progress  # "waiting for a TCU", while the lock-step handshake waits
        periodic = [f for f in (config.on_period, self._record_truth if config.truth else None) if f is not None]
        if periodic:  # called by the runner as it sends each tick (not a listener: that would cost each frame)
            runner = self.runner
            runner.on_tick = lambda: [f(runner) for f in periodic]
        self.runner.inject(self.faults_by_side["plant"], config.fault_seed)
        if self.runner.bus is not plant_bus:
            stack.callback(self.runner.bus.shutdown)
        if tcu_bus is not None:
            self._attach_tcu(tcu_bus)
        elif process is not None and isinstance(process, EcuStubProcess) and process.faults:
            self._progress("faults on the TCU's frames: passed to ecu-stub, which counts them (see its output)")
            self.runner.faults_in_tcu = [spec.describe() for spec in process.faults]
            self.runner.link.excuse(answers_lost_by(process.faults))  # a known fault is no lost TCU
        self._process = process

    # ---- set-up ----------------------------------------------------------------------------------------------
    def _check_paths(self) -> None:
        for option, path in (("log", self.config.log), ("summary", self.config.summary),
                             ("tcu_output", self.config.tcu_output)):
            check_output_path(option, None if path is None else str(path))

    def _binding(self) -> tuple[PlantIO, dict[str, dict[str, object]], dict[str, float]]:
        """The plant's messages and signals on the DBC, their protection and receive timeouts [s]: the binding's
        (checked against the DBC: :class:`dsg_hil.protocol.binding.BindingError` naming the file), else the shipped
        DBC's."""
        self.binding: Binding | None = None
        if self.config.binding is None:
            return SHIPPED, {}, {}
        binding = self.binding = load_binding(self.config.binding, db=self.db)
        return from_binding(binding), binding.protection, {m: ms / 1000 for m, ms in binding.timeouts_ms.items()}

    def _check_bundled_tcu(self) -> None:
        """The bundled TCU (ecu-stub) on the run's matrix: its messages and signals from the same binding as the
        plant's (:mod:`ecu_stub.tcu_io`); one it needs unmapped fails here, naming the binding file and the
        quantity, before anything is opened."""
        self.tcu_io: Any = None
        if self.config.tcu != ECU_STUB:
            return
        from ecu_stub.tcu_io import SHIPPED as SHIPPED_TCU  # noqa: PLC0415 - the TCU's, when it is the bundled one
        from ecu_stub.tcu_io import TcuIO  # noqa: PLC0415

        if self.binding is None and self.config.dbc is None:
            self.tcu_io = SHIPPED_TCU
            return
        self.tcu_io = TcuIO(self.binding if self.binding is not None else load_binding(None, db=self.db))

    def _check_tcu_factory(self) -> None:
        """A factory on a binding's matrix: built with the TCU's I/O of that binding where it takes ``io``
        (:class:`dsg_hil.fmi.controller.ControllerFmu`'s does); one that takes ``(db, bus)`` only builds the
        shipped DBC's frames, so it fails here (an InputError naming the binding file) unless the binding leaves
        the TCU's frames as they are."""
        tcu = self.config.tcu
        if tcu is None or isinstance(tcu, str | TcuProcess) or self.binding is None:
            return
        from ecu_stub.tcu_io import SHIPPED as SHIPPED_TCU  # noqa: PLC0415 - the TCU's I/O, for a factory
        from ecu_stub.tcu_io import TcuIO  # noqa: PLC0415

        io = TcuIO(self.binding)
        if takes_io(tcu):
            self.tcu_io = io
        elif any(getattr(io, name) != getattr(SHIPPED_TCU, name) for name in _TCU_FRAMES):
            raise InputError(f"--binding {self.binding.path}: moves the TCU's frames off the shipped DBC's, and the "
                             f"controller given (RunConfig.tcu, a factory (db, bus)) builds those; give one taking "
                             f"io (db, bus, io: an ecu_stub.tcu_io.TcuIO), or run it on the shipped matrix")

    def _plant_codec(self) -> Codec:
        """The plant's codec: a DBC without a message or signal the plant sends or reads (the TCU's among them)
        fails here, naming the file, before anything is opened or written."""
        try:
            return Codec(self.db, self.io.uses, reference=self.config.reference_codec, protection=self._protection,
                         timeouts=self._timeouts)
        except ProtocolError as exc:
            name = "the DBC given" if isinstance(self.config.dbc, Database) else self.config.dbc or "the shipped DBC"
            raise ProtocolError(f"{name}: {exc}") from None

    def _calibration(self) -> Any:
        """The bundled TCU's calibration, loaded now so a bad file fails before anything opens (None: default)."""
        path = self.config.calibration
        if path is None:
            return None
        if self.config.tcu != ECU_STUB:
            raise InputError(f"calibration {path}: is the bundled TCU's (ecu-stub); give your TCU its own")
        from ecu_stub.calibration import load_calibration  # noqa: PLC0415 - the TCU's, when one is given

        return load_calibration(path)

    def _bus_config(self) -> tuple[dict[str, Any], bool]:
        """The bus configuration, and whether the plant and an in-process TCU share a direct in-process bus."""
        config = self.config
        if isinstance(config.tcu, str) and config.tcu != ECU_STUB:
            raise InputError(f"RunConfig.tcu {config.tcu!r}: {ECU_STUB!r}, a factory, a TcuProcess or None")
        if config.mode not in ("lockstep", "realtime"):
            raise InputError(f"RunConfig.mode {config.mode!r}: 'lockstep' or 'realtime'")
        in_process = config.tcu is not None and not isinstance(config.tcu, TcuProcess)
        if config.bus is None:
            if not in_process:
                raise InputError("RunConfig: a TCU process or an external TCU needs a bus (bus=None is the "
                                 "in-process bus)")
            return {"interface": "local", "channel": private_channel()}, True
        bus = dict(config.bus)
        direct = in_process and config.direct and bus.get("interface") == "virtual" and config.mode == "lockstep"
        if in_process and bus.get("interface") != "virtual":
            if config.tcu != ECU_STUB:
                raise InputError(f"RunConfig: a TCU in this process needs bus None or interface 'virtual', not "
                                 f"{bus.get('interface')!r} (give a TcuProcess)")
        return bus, direct

    def _open_buses(self, direct: bool) -> tuple[can.BusABC, can.BusABC | None]:
        """The plant's bus and, for a TCU in this process, its own end of the same bus."""
        channel = str(self.bus_config["channel"])
        if direct:
            pair: tuple[can.BusABC, can.BusABC] = local_pair(channel)
            for end in pair:
                self._stack.callback(end.shutdown)
            return pair
        fd = has_fd(self.db.get_message_by_name(name) for name in self.io.uses)
        plant_bus = open_bus(self.bus_config, receive=[self.db.get_message_by_name(name) for name in self.io.rx],
                             fd=fd)
        self._stack.callback(plant_bus.shutdown)
        if self._tcu_in_process():
            tcu_bus = open_bus(self.bus_config, fd=fd)
            self._stack.callback(tcu_bus.shutdown)
            return plant_bus, tcu_bus
        return plant_bus, None

    def _tcu_in_process(self) -> bool:
        tcu = self.config.tcu
        if tcu is None or isinstance(tcu, TcuProcess):
            return False
        return tcu != ECU_STUB or self.bus_config["interface"] in ("local", "virtual")

    def _listeners(self) -> tuple[FrameListener, ...]:
        config = self.config
        listeners = tuple(config.listeners)
        if config.log is not None:
            log = FrameLog(str(config.log), log_channel(self.bus_config), option="log")
            self._stack.callback(log.stop)
            listeners = (*listeners, log)
        if config.capture:
            listeners = (*listeners, self.frames.append)
        return listeners

    def _record_truth(self, runner: PlantRunner) -> None:
        self._truth.append((runner.tick * runner.period, runner.out))

    def _tcu_process(self) -> TcuProcess | None:
        """The TCU process to start, if the TCU is one; TCU-side faults checked against the kind of TCU."""
        tcu, side = self.config.tcu, self.faults_by_side["tcu"]
        if tcu is None:
            if side:
                raise FaultError(f"{side[0].origin}: changes the TCU's frames: give it to ecu-stub (--fault), not "
                                 f"to the plant")
            return None
        if self._tcu_in_process():
            return None
        process = EcuStubProcess() if tcu == ECU_STUB else tcu
        assert isinstance(process, TcuProcess)
        if isinstance(process, EcuStubProcess):
            # the TCU waits for a silent plant as long as the plant waits for a silent TCU
            config = self.config  # (files as absolute paths; a loaded database is not passed on)
            calibration, dbc, binding = (None if path is None or isinstance(path, Database) else
                                         str(Path(path).resolve())
                                         for path in (config.calibration, config.dbc, config.binding))
            return replace(process, faults=tuple(side), fault_seed=self.config.fault_seed, calibration=calibration,
                           idle_exit=max(self.config.reply_timeout, 2.0), quiet=self.config.quiet,
                           dbc=dbc or process.dbc, binding=binding or process.binding)
        if side:
            raise InputError(f"{side[0].origin}: changes the controller's frames: a controller process injects "
                             f"its own (ecu-stub: --fault)")
        return process

    def _attach_tcu(self, tcu_bus: can.BusABC) -> None:
        """The TCU in this process, on its end of the bus, behind the TCU-side faults."""
        tcu = self.config.tcu
        factory = None if isinstance(tcu, str) or isinstance(tcu, TcuProcess) else tcu
        self.tcu, faulty = attach_tcu(self.runner, tcu_bus, self.db, self.faults_by_side["tcu"],
                                      self.config.fault_seed, factory, self.calibration, self.tcu_io)
        if faulty is not tcu_bus:
            self._stack.callback(faulty.shutdown)

    def _progress(self, message: str) -> None:
        if self.config.progress is not None:
            self.config.progress(message)

    # ---- running ---------------------------------------------------------------------------------------------
    def run(self) -> Summary:
        """Run the scenario to its end (or until it is stopped); returns the finished summary."""
        config, runner = self.config, self.runner
        with setup_frozen():
            if self._process is not None:
                self._run_with_process(self._process)
            elif self.tcu is not None and config.mode == "lockstep":
                answer_at_once(runner)
                runner.run_lockstep(config.reply_timeout, pump=self.tcu.pump, startup_timeout=config.startup_timeout)
            elif self.tcu is not None:
                self._run_realtime_with_thread()
            else:
                self._drive()
        return self.summary()

    def _drive(self, pump: Callable[[], None] | None = None) -> None:
        if self.config.mode == "lockstep":
            self.runner.run_lockstep(self.config.reply_timeout, pump=pump, startup_timeout=self.config.startup_timeout)
            return
        self.runner.run_realtime()
        if not self.runner.rx.received:  # a mistyped channel must not look like a clean run
            raise PeerTimeout(f"real time: not one frame from a TCU in the {self.scenario.duration_s:g} s run (the "
                              f"plant ran on unpowered hydraulics throughout): is the TCU on {self.interface}?")

    def _run_realtime_with_thread(self) -> None:
        """Real time with the TCU in this process: it serves the bus in a thread of its own."""
        errors: list[BaseException] = []
        done = threading.Event()

        def serve() -> None:
            try:
                self.tcu.run(should_stop=done.is_set)
            except BaseException as exc:  # noqa: BLE001 - re-raised in the main thread
                errors.append(exc)

        thread = threading.Thread(target=serve, name="tcu", daemon=True)
        thread.start()
        try:
            self.runner.run_realtime()
        finally:
            done.set()
            thread.join()
        if errors:
            raise errors[0]

    def _run_with_process(self, process: TcuProcess) -> None:
        output = self.config.tcu_output
        sink: IO[bytes] = open(output, "w+b") if output is not None else tempfile.TemporaryFile()  # noqa: SIM115
        with sink:
            try:
                proc = process.start(self.bus_config, sink)
            except OSError as exc:
                raise RunError(f"cannot start the TCU {process.command(self.bus_config)}: {exc}") from exc
            try:
                try:
                    status = proc.wait(timeout=0.5)
                except subprocess.TimeoutExpired:
                    status = None
                if status is not None:
                    raise PeerTimeout("the TCU process exited at start")
                self._drive(pump=lambda: _check_alive(proc, self.runner))
            except PeerTimeout as exc:  # (PeerLost too: the type decides the summary's stop reason)
                raise type(exc)(f"{exc} (TCU {' '.join(process.command(self.bus_config))}: "
                                f"{_process_state(proc, sink)})") from exc
            finally:
                process.stop(proc)

    # ---- results ---------------------------------------------------------------------------------------------
    def summary(self, **extra: Any) -> Summary:
        """The summary of the run so far (the finished one once the run is over), written to ``summary``."""
        runner = self.runner
        data = runner.summary.as_json(runner.frames(), self.scenario.name, self.config.mode, self.interface,
                                      self.scenario.duration_s)
        return _finish_summary(data, round(runner.plant.state.t, 3), runner.fault_summary(), extra,
                               self.config.summary, tuple(outside_range(self.scenario, self.params)))

    def truth(self) -> dict[str, np.ndarray]:
        """The plant each control period at the tick's time (``RunConfig.truth``): ``t`` [s] and each field of
        :class:`~dsg_hil.physics.plant.PlantOutputs` (SI; temperatures degC), e.g. ``truth()["T_CL"]``."""
        arrays = {"t": np.array([t for t, _ in self._truth], dtype=float)}
        for i, name in enumerate(PlantOutputs._fields):
            arrays[name] = np.array([out[i] for _, out in self._truth])
        return arrays

    # ---- context manager -------------------------------------------------------------------------------------
    def __enter__(self) -> Run:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            reason = _stop_reason(exc_type)
            if reason is not None:
                self.runner.summary.stop_reason = reason
                self.summary()
        finally:
            self._stack.close()


def _finish_summary(data: dict[str, Any], sim_time_s: float, faults: Mapping[str, Any], extra: Mapping[str, Any],
                    path: str | Path | None, outside: tuple[str, ...] = ()) -> Summary:
    """The :class:`Summary` of the bookkeeping's JSON ``data``, written to ``path`` if given."""
    summary = Summary(
        scenario=data.pop("scenario"), mode=data.pop("mode"), interface=data.pop("interface"),
        duration_s=data.pop("duration_s"), command_fallback=data.pop("command_fallback"),
        frames=data.pop("frames"), realtime_factor=data.pop("realtime_factor"),
        wall_time_s=data.pop("wall_time_s"), command_latency_ms=data.pop("command_latency_ms"),
        sim_time_s=sim_time_s, faults=faults, metrics=data, extra=extra, outside_range=outside)
    if path is not None:
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(summary.as_json(), indent=2) + "\n", encoding="utf-8")
    return summary


def unstarted_summary(reason: str, path: str | Path | None, scenario: str, mode: str, interface: str,
                      duration_s: float, fault_seed: int = 0) -> Summary:
    """The summary of a run a signal ended before :func:`open_run` had set it up (``reason``: ``interrupted``,
    ``terminated``): no control period ran, so it holds what is known, the bookkeeping of zero periods (no frame
    sent, ``sim_time_s`` 0, ``wall_time_s`` null) and the stop reason; written to ``path`` if given."""
    bookkeeping = RunSummary(dt=0.0, stop_reason=reason)  # the period's length: unused without a period
    frames: dict[str, Any] = dict.fromkeys(("sent", "received", "rejected", "retries", "lost", "duplicates",
                                            "unanswered_ticks", "unanswered_episodes", "probes"), 0)
    frames["by_message"] = {}
    data = bookkeeping.as_json(frames, scenario, mode, interface, duration_s)
    return _finish_summary(data, 0.0, {"seed": fault_seed, "injected": {}}, {}, path)


def _stop_reason(exc_type: type[BaseException] | None) -> str | None:
    """How a run that ends early ends: the summary's stop reason for the exception, None for others."""
    from ..common.cli import Terminated  # noqa: PLC0415

    if exc_type is None:
        return None
    for kind, reason in ((KeyboardInterrupt, "interrupted"), (Terminated, "terminated"), (PeerLost, "peer_lost"),
                         (PeerTimeout, "no_peer")):  # PeerLost before its base class PeerTimeout
        if issubclass(exc_type, kind):
            return reason
    return None


def open_run(config: RunConfig | None = None) -> Run:
    """Set up the run ``config`` describes (default: :class:`RunConfig`'s defaults): the scenario, parameters and
    DBC loaded, the buses, log and TCU opened, the faults in place. Bad input raises :class:`InputError` before
    anything runs or is written. Use it as a context manager (see the module's docstring)."""
    stack = ExitStack()
    try:
        return Run(config or RunConfig(), stack)
    except BaseException:
        stack.close()
        raise


def private_channel() -> str:
    """A channel name of this run's own (the in-process bus, python-can's virtual interface)."""
    return f"dsg_hil_loop_{os.getpid()}_{next(_channels)}"


@contextmanager
def setup_frozen() -> Iterator[None]:
    """The objects made so far (modules, the DBC and its codec, the compiled physics, the run's set-up) moved out of
    the cyclic garbage collector's way while the run goes (:func:`gc.freeze`): its full collections then walk only
    what the run makes, 3 % of a lock-step period (``bench/closed_loop_speed.py``); moved back afterwards
    (:func:`gc.unfreeze`), so that a process going on with more runs (a sweep's worker) collects them again. Left
    alone where something else has frozen objects: theirs to move back."""
    if gc.get_freeze_count():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def plant_for(scenario: Scenario, params: Params, dt: float = 1e-3) -> Plant:
    """A plant in the scenario's initial state (plate and oil temperatures, vehicle speed)."""
    return Plant(params, dt=dt, T_init=scenario.initial_temperatures(NODES), v_init=scenario.v_mps)


def answer_at_once(runner: PlantRunner) -> None:
    """An in-process TCU has answered when ``pump()`` returns: re-send a late tick at once instead of waiting
    on the wall clock (a fault that loses answers then costs no wall time, and no silence toward PeerLost)."""
    runner.retry_first_s = runner.retry_max_s = 0.0


def attach_tcu(runner: PlantRunner, bus: can.BusABC, db: Database, faults: Iterable[FaultSpec], fault_seed: int,
               tcu_factory: TcuFactory | None = None, calibration: Any = None,
               io: Any = None) -> tuple[Any, can.BusABC]:
    """A TCU in this process on ``bus``, its frames through the TCU-side ``faults`` (windows in the TCU's own time,
    its ``now``); the injector is registered on ``runner`` for the summary. Returns the TCU and its bus (``bus``
    behind the injector). Default TCU: the bundled ecu-stub, which knows the plant only by the DBC (with the
    plant's kind of codec) with ``calibration`` (an ``ecu_stub.calibration.TcuCalibration``; None: the shipped
    one), on the matrix as ``io`` (an ``ecu_stub.tcu_io.TcuIO``, of the run's binding; None: the shipped one)."""
    if tcu_factory is None:
        from ecu_stub.controller import CreepController  # noqa: PLC0415 - the TCU when one is attached
        from ecu_stub.runner import TcuRunner  # noqa: PLC0415
        from ecu_stub.tcu_io import SHIPPED as SHIPPED_TCU  # noqa: PLC0415

        reference = runner.codec.reference
        tcu_io = io if io is not None else SHIPPED_TCU
        controller = None if calibration is None else CreepController(calibration, tcu_io.matrix_steps)

        def tcu_factory(tcu_db: Database, tcu_bus: can.BusABC) -> Any:
            return TcuRunner(tcu_io.codec(tcu_db, reference), tcu_bus, controller, io=tcu_io)

        given = False
    else:
        given = io is not None  # a factory taking io (Run._check_tcu_factory): on the run's matrix
    built: list[Any] = []  # the TCU, once built: the fault clock reads its time
    tcu_bus, runner.injectors["tcu"] = with_faults(bus, db, faults, fault_seed, lambda: built[0].now)
    built.append(cast(Callable[..., Any], tcu_factory)(db, tcu_bus, io=io) if given else tcu_factory(db, tcu_bus))
    return built[0], tcu_bus


def takes_io(factory: Callable[..., Any]) -> bool:
    """Whether a ``RunConfig.tcu`` factory takes ``io`` (the TCU's I/O on the run's matrix) beside ``(db, bus)``."""
    try:
        return "io" in inspect.signature(factory).parameters
    except (TypeError, ValueError):  # no signature to read (a builtin): (db, bus)
        return False


# what a binding changes of the TCU's frames that a factory (db, bus) cannot follow: their messages, signals and
# numbers (their protection and timeouts it may set itself, in the codec it builds)
_TCU_FRAMES = ("uses", "names", "inputs", "tx_values", "state_values", "clutch_values")


def _check_alive(proc: subprocess.Popen[bytes], runner: PlantRunner) -> None:
    """Lock-step with a TCU process: one that exited ends the wait at once (no startup or reply timeout to sit
    out): :class:`PeerLost` in the run, :class:`PeerTimeout` before; the caller adds its exit status and output."""
    if proc.poll() is None:
        return
    if runner.clock() >= 0.0:  # the run proper has started
        raise PeerLost(f"the TCU process exited at lock-step tick {runner.tick}")
    raise PeerTimeout("the TCU process exited before it answered the presence probe")


def _output_tail(sink: IO[bytes]) -> str:
    sink.flush()
    sink.seek(0)
    tail = sink.read()[-2000:].decode(errors="replace").strip()
    return f"its output: {tail or '(none)'}"


def _process_state(proc: subprocess.Popen[bytes], sink: IO[bytes]) -> str:
    status = proc.poll()
    state = "still running" if status is None else f"exited with status {status}"
    return f"{state}; {_output_tail(sink)}"

