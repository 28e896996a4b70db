"""Faults from the command line and onto a node's bus: the one way ``dsg-hil run``, ``dsg-hil plant``,
``ecu-stub`` and :func:`dsg_hil.sim.loop.run_closed_loop` put an injector between a node and its bus."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING

from .spec import FaultSpec, parse_fault

if TYPE_CHECKING:
    import can
    from cantools.database.can import Database

    from ..profiles import FrameProtection
    from .injector import FaultInjector

__all__ = ["add_fault_arguments", "fault_counts", "faults_from_args", "with_faults"]


def add_fault_arguments(parser: argparse.ArgumentParser, whose: str,
                        examples: tuple[str, ...] = ("drop:TCU_CMD@10-12",
                                                     "stuck:PLANT_VEHICLE.VehicleSpeed@5-8,value=0"),
                        times: str = "the sender's seconds (simulated in lockstep)") -> None:
    """``--fault`` and ``--fault-seed``; ``examples``: faults the command accepts, ``times``: its fault clock."""
    parser.add_argument("--fault", action="append", default=[], metavar="SPEC",
                        help=f"inject a fault into {whose}, repeatable: KIND[:MESSAGE[.Signal]][@START-[END]]"
                             f"[,key=value ...], e.g. {' or '.join(repr(e) for e in examples)} (kinds and keys: "
                             f"docs/how-to/faults.md); times in {times}")
    parser.add_argument("--fault-seed", type=int, default=0, metavar="N",
                        help="seed of the draws of faults with probability < 1 (default 0)")


def faults_from_args(args: argparse.Namespace) -> list[FaultSpec]:
    return [parse_fault(text) for text in getattr(args, "fault", None) or ()]  # (a Namespace built in code: none)


def with_faults(bus: can.BusABC, db: Database, specs: Iterable[FaultSpec], seed: int, clock: Callable[[], float],
                protections: Mapping[str, FrameProtection] | None = None) -> tuple[can.BusABC, FaultInjector | None]:
    """``bus`` behind an injector of ``specs`` (checked against the DBC now), or ``bus`` itself if there are
    none. ``clock()`` is the sender's time: simulated in lockstep, its run time in real time; negative before
    the run starts (the lockstep handshake is never faulted). ``protections``: the node's messages' protections
    (its codec's, :meth:`~dsg_hil.protocol.codec.Codec.protections`), where they are not the database's."""
    from .injector import FaultInjector, FaultyBus  # noqa: PLC0415 - python-can and cantools, when needed

    specs = list(specs)
    if not specs:
        return bus, None
    injector = FaultInjector(db, specs, seed, protections)
    return FaultyBus(bus, injector, clock), injector


def fault_counts(injectors: dict[str, FaultInjector | None], seed: int) -> dict:
    """The summary's ``faults``: frames each specification hit (lockstep re-sends included) per side, and the
    seed; ``injected`` adds the sides up; ``not_encodable`` (only if any): frames hit whose changed value could
    not be encoded, sent unchanged."""
    out: dict = {"seed": seed, "injected": {}}
    for side, injector in injectors.items():
        if injector is None:
            continue
        counts = {spec.describe(): injector.counts[spec.describe()] for spec in injector.specs}
        out[side] = counts
        for key, n in counts.items():
            out["injected"][key] = out["injected"].get(key, 0) + n
        for key, n in injector.encode_errors.items():
            out.setdefault("not_encodable", {})[key] = out.get("not_encodable", {}).get(key, 0) + n
    return out
