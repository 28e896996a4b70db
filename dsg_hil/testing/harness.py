"""Test a controller against the plant: one call, :func:`run_plant`, runs a scenario in lockstep and gives the
summary, every decoded signal as a time series, the plant's truth each control period, and the log.

The controller is one of

* ``None``: the bundled ecu-stub, in this process (python-can ``virtual``); or an ecu-stub
  :class:`~ecu_stub.controller.CreepController` (e.g. with another calibration);
* a command line (``list`` of ``str``, or :class:`ControllerProcess`): started as a process on a
  ``udp_multicast`` group and port of the run's own (a compiled ECU, a script, ``ecu-stub`` itself);
* a Python object with ``step(t, inputs)`` (:class:`Controller`), run in this process;
* the path of a co-simulation FMU (``str`` or :class:`~pathlib.Path` ending in ``.fmu``): run through FMPy behind
  ecu-stub's bus side, in this process (:mod:`dsg_hil.fmi.controller`, extra ``fmi``).

The pytest plugin (:mod:`dsg_hil.testing.plugin`, fixture ``dsg_hil_run``) calls this with a directory per run.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TypeGuard

import can
from cantools.database.can import Database
import numpy as np

from ..common.errors import InputError
from ..physics.params import Params
from ..protocol import Codec
from ..protocol.bus import UDP_MULTICAST, fresh_udp_group
from ..protocol.diag import load_description
from ..protocol.diag_client import uds_client
from ..protocol.faults import FaultSpec
from ..sim.run import ECU_STUB, RunConfig, TcuFactory, open_run
from ..sim.scenario import Scenario
from .controllers import Controller, ControllerProcess, PythonControllerTcu
from .signals import Signals, decode_frames

__all__ = ["PlantRun", "run_plant"]

_UDS_CHANNELS = itertools.count()
ControllerLike = Controller | ControllerProcess | Sequence[str] | Any  # or None: the bundled ecu-stub


@dataclass
class PlantRun:
    """What a run gives.

    ``summary``: as ``dsg-hil run --summary`` writes it (:class:`dsg_hil.results.outcome.Summary` ``as_json()``).
    ``signals``: every frame on the bus (the plant's as it sent them, the controller's as the plant accepted
    them) decoded, see :class:`Signals`. ``truth``: the plant once per control period, at the tick's time,
    unquantised: ``truth["t"]`` [s] and each field of :class:`~dsg_hil.physics.plant.PlantOutputs` (SI: rad/s,
    Pa, N m, W; temperatures degC), e.g. ``truth["T_CL"]``, ``truth["v"]``. ``frames``: the frames themselves.
    ``log``: the log file (None if not asked for). ``controller_output``: the controller process's stdout and
    stderr (process controllers)."""

    summary: dict[str, Any]
    signals: Signals
    truth: dict[str, np.ndarray]
    frames: list[can.Message]
    log: Path | None
    controller_output: Path | None = None
    tcu: Any = None  # the TCU object of an in-process run (ecu-stub's TcuRunner), else None

    @contextmanager
    def uds(self, description: str | Path | None = None, timeout: float = 2.0) -> Iterator[Any]:
        """A UDS client (``udsoncan.client.Client`` over ``can-isotp``, extra ``diag``) of the run's ecu-stub, its
        DIDs decoding by ``description`` (None: ecu-stub's, ``dsg_hil/data/diag.toml``): after the run the TCU's
        diagnostic server answers on a python-can ``virtual`` channel of its own, the DTCs as the run left them.
        :func:`dsg_hil.protocol.diag_client.read_dtcs` / ``read_dids`` / ``clear_dtcs`` take the client. A TCU
        that ran as a process (or without diagnostics) has none here: talk to it during its run on the run's bus
        (:func:`~dsg_hil.protocol.diag_client.uds_client`)."""
        diag = getattr(self.tcu, "diag", None)
        if diag is None:
            raise InputError("PlantRun.uds: the run's TCU did not run in this process with diagnostics (ecu-stub); "
                             "talk to a TCU process on the run's bus during the run (uds_client)")
        channel = f"dsg-hil-uds-{id(self):x}-{next(_UDS_CHANNELS)}"
        stop = threading.Event()
        with ExitStack() as stack:
            server_bus = stack.enter_context(can.Bus(interface="virtual", channel=channel))
            client_bus = stack.enter_context(can.Bus(interface="virtual", channel=channel))
            thread = threading.Thread(target=diag.serve, args=(server_bus, stop), daemon=True)
            thread.start()
            stack.callback(thread.join)
            stack.callback(stop.set)
            yield stack.enter_context(uds_client(client_bus, load_description(description), diag.request_id,
                                                 diag.response_id, timeout=timeout))


def run_plant(controller: ControllerLike = None, *, scenario: Scenario | str | Path | None = None,
              duration: float | None = None, params: Params | str | Path | Mapping[str, float] | None = None,
              faults: Iterable[FaultSpec | str] | None = None, fault_seed: int = 0,
              out_dir: str | Path | None = None, log: str | None = "run.asc", reply_timeout: float = 5.0,
              startup_timeout: float = 60.0, dbc: str | Path | None = None,
              binding: str | Path | None = None) -> PlantRun:
    """Run ``scenario`` (default: the shipped creep scenario; a path to a scenario TOML or a
    :class:`~dsg_hil.sim.scenario.Scenario`) for ``duration`` s (default: the scenario's) with ``controller`` in
    lockstep.

    ``params``: a parameter file, a :class:`~dsg_hil.physics.params.Params`, or overrides of the shipped
    parameters by dotted key (``{"vehicle.m": 1900.0}``, SI units as in ``dsg-hil params``). ``faults``: fault
    specs or ``--fault`` strings (``"drop:TCU_CMD@2-2.1"``), default the scenario's ``[[fault]]`` tables; a
    process controller takes plant-side faults only (give it its own). ``out_dir``: where the log
    (``log``, by extension: ``.asc``, ``.blf``, ``.log`` ..., None for none) and the controller process's
    output go (needed for a log). ``dbc``, ``binding``: the communication matrix and which of its signals carry the
    plant's quantities (None: the shipped pair; the bundled ecu-stub, ``controller`` None, reads the same pair). Raises
    :class:`~dsg_hil.sim.runner.PeerTimeout` when the controller never answers
    the presence probe, :class:`~dsg_hil.sim.runner.PeerLost` when it falls silent for ``reply_timeout`` s."""
    out = Path(out_dir) if out_dir is not None else None
    if log is not None and out is None:
        raise InputError("run_plant: log needs out_dir (the directory to write it into)")
    process = controller if isinstance(controller, ControllerProcess) else \
        ControllerProcess(list(controller)) if _is_command(controller) else None
    output = out / "controller.out" if process is not None and out is not None else None
    config = RunConfig(scenario=scenario, duration=duration, params=params, dbc=dbc, binding=binding,
                       fault_seed=fault_seed,
                       faults=None if faults is None else list(faults),
                       log=None if log is None or out is None else out / log, tcu_output=output,
                       bus={"interface": UDP_MULTICAST, **fresh_udp_group()} if process is not None else None,
                       tcu=process if process is not None else _tcu_factory(controller), capture=True, truth=True,
                       reply_timeout=reply_timeout, startup_timeout=startup_timeout)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    with ExitStack() as stack:
        if _is_fmu(controller):
            from ..fmi.controller import open_controller  # noqa: PLC0415 - FMPy only for an FMU

            config = replace(config, tcu=stack.enter_context(open_controller(controller)).tcu_factory)
        run = stack.enter_context(open_run(config))
        summary = run.run()
    return PlantRun(summary.as_json(), decode_frames(run.db, run.frames), run.truth(), run.frames,
                    config.log if isinstance(config.log, Path) else None, output,
                    run.tcu if process is None else None)


def _is_fmu(controller: Any) -> TypeGuard[str | Path]:
    return isinstance(controller, (str, Path)) and str(controller).lower().endswith(".fmu")


def _is_command(controller: Any) -> TypeGuard[Sequence[str]]:
    return isinstance(controller, (list, tuple)) and bool(controller) and all(isinstance(a, str) for a in controller)


def _tcu_factory(controller: Any) -> str | TcuFactory:
    """How the in-process TCU is built: ecu-stub (``None`` or its controller) or a Controller."""
    if controller is None or _is_fmu(controller):  # an FMU: its factory is set once the FMU is open
        return ECU_STUB
    from ecu_stub.interface import TcuController
    from ecu_stub.runner import TCU_USES, TcuRunner
    from ecu_stub.tcu_io import TcuIO

    if isinstance(controller, TcuController):  # ecu-stub's CreepController (any calibration), or its like
        def tcu_runner(db: Database, bus: can.BusABC, io: TcuIO | None = None) -> TcuRunner:
            """On the run's binding's matrix (``io``), as the bundled ecu-stub; else the shipped DBC's."""
            if io is None:
                return TcuRunner(Codec(db, TCU_USES), bus, controller)
            return TcuRunner(io.codec(db), bus, controller, io=io)

        return tcu_runner
    if isinstance(controller, Controller):
        return lambda db, bus: PythonControllerTcu(Codec(db, TCU_USES), bus, controller)
    raise TypeError(f"controller: expected None, an ecu-stub CreepController (or an object with update(inputs, now) "
                    f"and cal), a command line (list of str), a "
                    f"ControllerProcess, an object with step(t, inputs) or an .fmu path; got "
                    f"{type(controller).__name__}")
