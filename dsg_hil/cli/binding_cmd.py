"""``dsg-hil binding check DBC BINDING``: a binding checked against its database before anything runs.
``dsg-hil binding init DBC``: a binding's skeleton for a database, printed (:mod:`dsg_hil.protocol.skeleton`)."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from . import command_help

if TYPE_CHECKING:
    from collections.abc import Mapping

    from ..protocol.binding import Binding

__all__ = ["add_subparser", "mapping_rows", "value_rows"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("binding", help=command_help("binding"),
                            description="check: read the binding (which signal of the DBC carries each quantity "
                                        "of the plant, in which unit; the shipped one is dbc/dsg_hil.binding.toml) "
                                        "with its DBC (or ARXML) and print every problem, one line each, exit 2: "
                                        "a message or signal not in the database, a unit that does not convert, "
                                        "a range or resolution that cannot carry the quantity's, a quantity the "
                                        "plant needs unmapped, a message without a cycle time, a protection that "
                                        "does not fit its frame. With none, print the mapping as a table (and "
                                        "the numbers the matrix sends for the TCU's states and clutches, where "
                                        "the binding gives values). init: print a binding's skeleton for the "
                                        "database (every quantity of the plant, the ones it needs marked, under "
                                        "each the signals that can carry it, commented out; the state's and "
                                        "clutch's with values where the signal has a value table): "
                                        "dsg-hil binding init my_ecu.dbc > my_ecu.binding.toml")
    parser.add_argument("action", choices=("check", "init"),
                        help="check: the binding against the database; init: a binding's skeleton for it")
    parser.add_argument("dbc", metavar="DBC", help="the communication matrix (DBC, or ARXML through cantools)")
    parser.add_argument("binding", metavar="BINDING", nargs="?", help="the binding TOML (check only)")
    parser.set_defaults(func=_do_binding, parser=parser)


def mapping_rows(binding: Binding) -> list[tuple[str, ...]]:
    """(quantity, direction, message.signal, unit, resolution, cycle ms, protection, frame) of each signal the
    plant uses, the lock-step tick and echo included (their quantity in brackets); frame: ``CAN(8)`` for a classic
    frame of 8 bytes, ``FD(16,BRS)`` for a CAN FD one of 16 bytes with bit-rate switch."""
    from ..protocol.codec import bitrate_switch, frame_length  # noqa: PLC0415 - cantools at run time only
    from ..protocol.profiles import protection_for  # noqa: PLC0415

    db = binding.db
    roles = {**{key: (quantity, binding.units[quantity]) for key, (quantity, _) in binding.signals.items()},
             binding.sync: ("(lock-step tick)", None), binding.echo: ("(lock-step echo)", None)}
    rows: list[tuple[str, ...]] = []
    for direction, table in (("send", binding.tx), ("send", {binding.sync[0]: (binding.sync[1],)}),
                             ("read", binding.rx)):
        for message_name, signals in table.items():
            message = db.get_message_by_name(message_name)
            protection = protection_for(message, binding.protection.get(message_name)).profile
            frame = f"CAN({message.length})" if not message.is_fd else \
                f"FD({frame_length(message)}{',BRS' if bitrate_switch(message, db) else ''})"
            for signal_name in signals:
                signal = message.get_signal_by_name(signal_name)
                quantity, unit = roles[message_name, signal_name]
                rows.append((quantity, direction, f"{message_name}.{signal_name}",
                             unit if unit is not None else signal.unit or "-", f"{signal.scale:g}",
                             str(message.cycle_time), protection, frame))
    return rows


def value_rows(binding: Binding) -> list[tuple[str, ...]]:
    """(quantity, the TCU's name, its number, ``->``, the matrix's number, its name in the signal's value table) of
    each value of each quantity whose entry gives ``values`` (:data:`dsg_hil.protocol.binding.VALUED`)."""
    from ..protocol.binding import shipped_numbers  # noqa: PLC0415

    where = {quantity: key for key, (quantity, _) in binding.signals.items()}
    rows: list[tuple[str, ...]] = []
    for quantity, numbers in binding.values.items():
        message, signal = where[quantity]
        choices: Mapping[int, object] = binding.db.get_message_by_name(message).get_signal_by_name(signal).choices or {}
        names = {int(number): str(name) for number, name in choices.items()}
        for ours, number in shipped_numbers(quantity).items():
            rows.append((quantity, ours, str(number), "->", str(numbers[number]), names[numbers[number]]))
    return rows


def _table(rows: list[tuple[str, ...]]) -> None:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    for row in rows:
        print("  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip())


def _do_binding(args: argparse.Namespace) -> int:
    from ..protocol import load_dbc  # noqa: PLC0415 - cantools at run time only
    from ..protocol.binding import BindingError, check_binding  # noqa: PLC0415

    if (args.action == "check") != (args.binding is not None):
        args.parser.error("check takes DBC and BINDING" if args.action == "check" else "init takes DBC only")
    db = load_dbc(args.dbc)
    if args.action == "init":
        from ..protocol.skeleton import binding_skeleton  # noqa: PLC0415

        sys.stdout.write(binding_skeleton(db, args.dbc))
        return 0
    binding, problems = check_binding(args.binding, db)
    if binding is None:
        for line in problems[:-1]:
            print(f"error: {line}", file=sys.stderr)
        raise BindingError(problems[-1])
    header = ("quantity", "dir", "message.signal", "unit", "resolution", "cycle ms", "protection", "frame")
    _table([header, *mapping_rows(binding)])
    if binding.values:  # the numbers of the TCU's states and clutches on the matrix, where its value tables differ
        print()
        _table([("values", "TCU", "number", "", "matrix", "name"), *value_rows(binding)])
    print(f"{args.binding}: {len(binding.signals)} quantities on {len(binding.tx) + 1} messages sent, "
          f"{len(binding.rx)} read: no problem")
    return 0
