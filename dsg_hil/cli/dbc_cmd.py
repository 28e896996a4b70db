"""``dsg-hil dbc``: the CAN contract at a glance and the bus load it implies."""

from __future__ import annotations

import argparse

from ..common.errors import ResultError
from . import command_help
from .common import positive_number

__all__ = ["LOAD_LIMIT", "add_subparser"]

LOAD_LIMIT = 0.30


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("dbc", help=command_help("dbc"),
                            description="List every message of the DBC with its ID, sender, cycle time and "
                                        f"worst-case bus load (bit stuffing included). Exit 3 above {LOAD_LIMIT:.0%}.")
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: the shipped dbc/dsg_hil.dbc)")
    parser.add_argument("--bitrate", type=positive_number, default=500_000.0, help="bit/s (default 500000)")
    parser.set_defaults(func=_do_dbc)


def _do_dbc(args: argparse.Namespace) -> int:
    from ..protocol import load_dbc  # noqa: PLC0415 - cantools at run time only
    from ..protocol.busload import bus_load, frame_bits  # noqa: PLC0415

    db = load_dbc(args.dbc)
    total, rows = bus_load(db, args.bitrate)
    senders = {m.name: ",".join(m.senders) for m in db.messages}
    ids = {m.name: m.frame_id for m in db.messages}
    print(f"{'message':<16}{'ID':>7}  {'sender':<7}{'cycle ms':>9}{'frames/s':>10}{'load':>8}")
    for name, cycle, rate, load in rows:
        print(f"{name:<16}{ids[name]:>#7x}  {senders[name]:<7}{cycle:>9}{rate:>10.1f}{load:>8.2%}")
    print(f"total at {args.bitrate / 1000:g} kbit/s (worst case {frame_bits(8)} bits per 8-byte frame): "
          f"{total:.1%} (limit {LOAD_LIMIT:.0%})")
    if total > LOAD_LIMIT:
        raise ResultError(f"bus load {total:.1%} at {args.bitrate / 1000:g} kbit/s above the limit {LOAD_LIMIT:.0%}")
    return 0
