"""The controllers a test can put on the plant's bus: a command line started as a process, or a Python object.

(The bundled ecu-stub needs nothing here: :func:`dsg_hil.sim.loop.attach_tcu` builds it.)
"""

from __future__ import annotations

import json
import os
import subprocess
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Protocol, runtime_checkable

import can

from ecu_stub.runner import REQUIRED, TCU_RX, TCU_TX

from ..common.errors import RunError
from ..protocol import Codec
from ..protocol.bus import bus_args
from ..sim.run import stop_process
from ..protocol.lockstep import Frames, LockstepResponder, frame_io

__all__ = ["BUS_ARGS", "Controller", "ControllerProcess", "PythonControllerTcu"]


@runtime_checkable
class Controller(Protocol):
    """A controller in Python, run by the plant in lockstep once per control period (the TCU_CMD cycle, 10 ms).

    ``step(t, inputs)``: ``t`` is the simulated time [s] of the period; ``inputs`` holds the newest decoded values
    of each plant message a TCU reads (``PLANT_ENGINE``, ``PLANT_SPEEDS``, ``PLANT_VEHICLE``, ``PLANT_PRESSURE``,
    ``PLANT_OIL_TEMP``, ``DRIVER``), ``{message: {signal: value}}`` in DBC units (r/min, m/s, MPa, degC, %); a
    message missing for 3 of its cycle times, or failing its counter or CRC check, is left out (as a real TCU's
    timeout would). It returns the ``TCU_CMD`` signals ``P_CL_Cmd`` and ``P_CH_Cmd`` [MPa] and optionally
    ``DecelRequest`` [m/s^2, asked of the brakes]; a missing one is 0.
    ``SyncEcho``, ``Counter`` and ``CRC`` are filled in for it, and a repeated tick is answered without a new step.

    Optional: ``status(t)`` returning ``TCU_STATUS`` signals (``State``, ``ActiveClutch``, ``BrakeRequest``,
    ``T_CL_Pred``, ``T_CH_Pred``, ``FaultBits``), sent every 100 ms; without it no TCU_STATUS is sent and the
    summary's TCU fields (handovers, predictions) stay empty. One object per run: it is not reset.
    """

    def step(self, t: float, inputs: Mapping[str, Mapping[str, float]]) -> Mapping[str, float]: ...


class PythonControllerTcu:
    """A :class:`Controller` on the plant's bus, in lockstep: ecu-stub's bus side (the protocol's TCU end,
    :class:`~dsg_hil.protocol.lockstep.LockstepResponder`: answers, repeated ticks, counters and CRC, receive
    checks) around the controller's ``step``. ``pump()`` handles what waits; ``now`` is its time (fault windows)."""

    def __init__(self, codec: Codec, bus: can.BusABC, controller: Controller) -> None:
        self.user = controller
        self.now = -1.0
        send, recv = frame_io(bus)
        self.link = LockstepResponder(codec, TCU_RX, TCU_TX, REQUIRED, step=self._step, restart=self._restart,
                                      send=send, recv=recv)

    def pump(self) -> None:
        self.link.pump()

    def _restart(self, now: float) -> None:
        self.now = now  # the controller is not reset: one object per run

    def _step(self, now: float, echo: int) -> Frames:
        self.now = now
        rx, tx = self.link.rx, self.link.tx
        inputs = {name: dict(rx.values(name)) for name in REQUIRED if rx.valid(name, now)}
        values = {"TCU_CMD": {**self.user.step(now, inputs), "SyncEcho": echo}}
        status = getattr(self.user, "status", None)
        if status is not None:
            values["TCU_STATUS"] = dict(status(now))
        due = sorted(tx.due(now), key=lambda name: name == "TCU_CMD")  # TCU_CMD last, as ecu-stub
        return [(tx.ids[name], tx.data(name, values[name])) for name in due if name in values]


BUS_ARGS = "{bus_args}"


@dataclass
class ControllerProcess:
    """A controller started as a process on the plant's bus, a ``udp_multicast`` group and port of the run's own.

    ``argv``: the command line. An item ``"{bus_args}"`` becomes python-can's bus options
    (``-i udp_multicast -c GROUP --bus-kwargs port=PORT``, as ``ecu-stub`` and ``can.logger`` take them); inside
    any item ``{interface}``, ``{channel}`` (the group) and ``{port}`` are replaced. The process also gets
    ``CAN_INTERFACE``, ``CAN_CHANNEL`` and ``CAN_CONFIG`` (``{"port": PORT}``) in its environment, so a python-can
    program's ``can.Bus()`` opens the run's bus with no options. It must answer the plant's lockstep protocol
    (``docs/reference/contract.md``); it is stopped (SIGTERM, then SIGKILL after ``stop_timeout`` s) when the run
    ends."""

    argv: Sequence[str]
    env: Mapping[str, str] = field(default_factory=dict)  # added to this process's environment
    cwd: str | Path | None = None
    stop_timeout: float = 5.0

    def command(self, config: Mapping[str, Any]) -> list[str]:
        """The command line for the bus ``config``."""
        names = {"interface": config["interface"], "channel": config["channel"], "port": config.get("port", "")}
        argv: list[str] = []
        for item in self.argv:
            argv += bus_args(dict(config)) if item == BUS_ARGS else [str(item).format(**names)]
        return argv

    def start(self, config: Mapping[str, Any], output: IO[bytes]) -> subprocess.Popen[bytes]:
        extra = {k: v for k, v in config.items() if k not in ("interface", "channel")}
        env = {**os.environ, "CAN_INTERFACE": str(config["interface"]), "CAN_CHANNEL": str(config["channel"]),
               "CAN_CONFIG": json.dumps(extra), **self.env}
        try:
            return subprocess.Popen(self.command(config), stdout=output, stderr=subprocess.STDOUT, env=env,
                                    cwd=self.cwd)
        except OSError as exc:
            raise RunError(f"cannot start the controller {list(self.argv)}: {exc}") from exc

    def stop(self, proc: subprocess.Popen[bytes]) -> None:
        stop_process(proc, self.stop_timeout)
