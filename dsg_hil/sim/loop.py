"""The closed loop in one process: the plant and a TCU in lockstep on a direct in-process bus
(:mod:`dsg_hil.protocol.local`; python-can's ``virtual`` interface on request, the same frames bit for bit).

:func:`run_closed_loop` is :func:`dsg_hil.sim.run.open_run` with the arguments the tests, the benchmarks, the
safety sweep and the report use most, giving the summary as a JSON dict. The TCU is the bundled ecu-stub unless
another ``TcuRunner``-like object is given; it talks to the plant only through CAN frames, exactly as on vcan0.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import can
from cantools.database.can import Database

from ..physics.params import Params
from ..protocol.faults import FaultSpec
from ..protocol.frame import FrameListener
from .run import (ECU_STUB, RunConfig, TcuFactory, answer_at_once, attach_tcu, open_run, plant_for,
                  private_channel)
from .runner import PlantRunner
from .scenario import Scenario

__all__ = ["TRANSPORTS", "LoopResult", "answer_at_once", "attach_tcu", "plant_for",
           "run_closed_loop"]

TRANSPORTS = ("local", "virtual")  # of run_closed_loop


@dataclass
class LoopResult:
    """What a closed-loop run gives: the summary (as ``dsg-hil run --summary`` writes it), the plant runner (its
    plant holds the final truth) and, if asked for, every frame on the bus with simulated timestamps."""

    summary: dict[str, Any]
    runner: PlantRunner
    frames: list[can.Message]


def run_closed_loop(scenario: Scenario, params: Params | None = None, *, db: Database | None = None,
                    tcu_factory: TcuFactory | None = None, capture: bool = False,
                    listeners: Sequence[FrameListener] = (),
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
    if transport not in TRANSPORTS:
        raise ValueError(f"transport {transport!r}: one of {', '.join(TRANSPORTS)}")
    bus = None if transport == "local" else {"interface": "virtual", "channel": private_channel()}
    config = RunConfig(scenario=scenario, params=params, dbc=db, tcu=tcu_factory or ECU_STUB, bus=bus, direct=False,
                       faults=None if faults is None else list(faults), fault_seed=fault_seed, capture=capture,
                       listeners=listeners, on_period=on_period, progress=progress, reference_codec=reference_codec)
    with open_run(config) as run:
        summary = run.run()
    return LoopResult(summary.as_json(), run.runner, run.frames)
