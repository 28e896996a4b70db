"""The closed loop in one process: the plant and a TCU in lockstep on a direct in-process bus
(:mod:`dsg_hil.protocol.local`; python-can's ``virtual`` interface on request, the same frames bit for bit).

One entry point, :func:`run_closed_loop`, for everything that runs the real loop without a second process: the
tests, the benchmarks, the safety sweep and the report. The TCU is the bundled ecu-stub unless another
``TcuRunner``-like object is given; it talks to the plant only through CAN frames, exactly as it does on vcan0.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import can
from cantools.database.can import Database

from ..physics.params import Params, load_params
from ..physics.thermal import NODES
from ..physics.plant import Plant
from .plant_io import PLANT_USES, SYNC
from ..protocol import Codec, load_dbc
from ..protocol.faults import FaultSpec, check_faults, with_faults
from ..protocol.local import local_pair
from .runner import PlantRunner
from .scenario import Scenario

_channels = itertools.count()
TRANSPORTS = ("local", "virtual")  # of run_closed_loop


def plant_for(scenario: Scenario, params: Params, dt: float = 1e-3) -> Plant:
    """A plant in the scenario's initial state (plate and oil temperatures, vehicle speed)."""
    return Plant(params, dt=dt, T_init=scenario.initial_temperatures(NODES), v_init=scenario.v_mps)


def answer_at_once(runner: PlantRunner) -> None:
    """An in-process TCU has answered when ``pump()`` returns: re-send a late tick at once instead of waiting
    on the wall clock (a fault that loses answers then costs no wall time, and no silence toward PeerLost)."""
    runner.retry_first_s = runner.retry_max_s = 0.0


def at_each_tick(db: Database, call: Callable[[], None]) -> Callable[[can.Message], None]:
    """A plant listener that calls ``call()`` at each SIM_SYNC tick the plant sends (once per control period:
    listeners see first transmissions only, never re-sends or the presence probe)."""
    sync_id = db.get_message_by_name(SYNC).frame_id

    def listener(msg: can.Message) -> None:
        if msg.arbitration_id == sync_id:
            call()
    return listener


@dataclass
class LoopResult:
    """What a closed-loop run gives: the summary (as ``dsg-hil run --summary`` writes it), the plant runner (its
    plant holds the final truth) and, if asked for, every frame on the bus with simulated timestamps."""

    summary: dict[str, Any]
    runner: PlantRunner
    frames: list[can.Message]


def attach_tcu(runner: PlantRunner, bus: can.BusABC, db: Database, faults: Iterable[FaultSpec], fault_seed: int,
               tcu_factory: Callable[[Database, can.BusABC], Any] | None = None) -> tuple[Any, can.BusABC]:
    """A TCU in this process on ``bus``, its frames through the TCU-side ``faults`` (windows in the TCU's own time,
    its ``now``); the injector is registered on ``runner`` for the summary. Returns the TCU and its (wrapped) bus.
    Default TCU: the bundled ecu-stub, which knows the plant only by the DBC (with the plant's kind of codec)."""
    if tcu_factory is None:
        from ecu_stub.runner import TCU_USES, TcuRunner

        reference = runner.codec.reference

        def tcu_factory(tcu_db: Database, tcu_bus: can.BusABC) -> Any:
            return TcuRunner(Codec(tcu_db, TCU_USES, reference=reference), tcu_bus)
    built: list[Any] = []  # the TCU, once built: the fault clock reads its time
    tcu_bus, runner.injectors["tcu"] = with_faults(bus, db, faults, fault_seed, lambda: built[0].now)
    built.append(tcu_factory(db, tcu_bus))
    return built[0], tcu_bus


def run_closed_loop(scenario: Scenario, params: Params | None = None, *, db: Database | None = None,
                    tcu_factory: Callable[[Database, can.BusABC], Any] | None = None, capture: bool = False,
                    listeners: tuple[Callable[[can.Message], None], ...] = (),
                    progress: Callable[[str], None] | None = None, faults: Iterable[FaultSpec] | None = None,
                    fault_seed: int = 0, on_period: Callable[[PlantRunner], None] | None = None,
                    transport: str = "local", reference_codec: bool = False) -> LoopResult:
    """Run ``scenario`` to its end with the plant and the TCU in lockstep on a private in-process bus.

    ``tcu_factory(db, bus)`` builds the TCU (default: ecu-stub's ``TcuRunner``); it must offer ``pump()``,
    which handles every frame already waiting, and a ``now`` attribute (its time for the fault windows).
    ``capture`` keeps every frame the plant sent or accepted (as sent: faults on the plant's frames are not in
    it). ``faults`` (default: the scenario's ``[[fault]]`` tables) go on the bus of the side whose frames they
    change, each side drawing from its own generator seeded ``fault_seed``; the summary's ``faults`` counts the
    frames each hit. ``on_period(runner)`` is called once per control period, as the plant sends the period's
    SIM_SYNC tick: ``runner.out`` is then the plant at the tick's time (before the TCU answers it).
    ``transport``: "local" (:mod:`dsg_hil.protocol.local`) or "virtual" (python-can's); ``reference_codec``:
    encode and decode through cantools (:class:`Codec` ``reference``). Both change only the speed (the baseline
    of ``bench/closed_loop_speed.py``), never a frame."""
    params = params or load_params()
    db = db or load_dbc()
    if transport not in TRANSPORTS:
        raise ValueError(f"transport {transport!r}: one of {', '.join(TRANSPORTS)}")
    channel = f"dsg_hil_loop_{os.getpid()}_{next(_channels)}"
    frames: list[can.Message] = []
    if capture:
        listeners = (*listeners, frames.append)
    if on_period is not None:
        listeners = (*listeners, at_each_tick(db, lambda: on_period(runner)))
    by_side = check_faults(scenario.faults if faults is None else faults, db)
    buses: list[can.BusABC] = list(local_pair(channel)) if transport == "local" else \
        [can.Bus(interface="virtual", channel=channel), can.Bus(interface="virtual", channel=channel)]
    try:
        runner = PlantRunner(plant_for(scenario, params), scenario, Codec(db, PLANT_USES, reference=reference_codec),
                             buses[0], listeners, progress)
        runner.inject(by_side["plant"], fault_seed)
        tcu, tcu_bus = attach_tcu(runner, buses[1], db, by_side["tcu"], fault_seed, tcu_factory)
        buses += [runner.bus, tcu_bus]
        answer_at_once(runner)
        summary = runner.run_lockstep(pump=tcu.pump)
    finally:
        for bus in reversed(buses):
            bus.shutdown()
    data = summary.as_json(runner.frames(), scenario.name, "lockstep", f"{transport}:{channel}", scenario.duration_s)
    data["faults"] = runner.fault_summary()
    return LoopResult(data, runner, frames)

