"""A binding skeleton from a database (``dsg-hil binding init DB``): the TOML of a binding (:mod:`.binding`) with
every quantity of the plant listed, the ones it needs marked, and under each the database's signals whose unit
converts to the quantity's, commented out: the ones that can carry its range and resolution first (the narrowest
range first), then the others with the reason they cannot. The simulation database's messages are added on IDs the
matrix leaves free, so the truth quantities have their candidates too. Under a candidate of the TCU's state or
active clutch (:data:`~.binding.VALUED`) that has a value table, its entry with ``values`` is offered too: each of
the TCU's names with the table's name guessed for it (``"?"`` where none is), and the table's numbers and names."""

from __future__ import annotations

import copy
import re

import cantools
from cantools.database.can import Database, Message, Signal

from .binding import QUANTITIES, SIM_DATABASE, VALUED, add_simulation, conversion, shipped_numbers, signal_fit
from .ranges import signal_range

__all__ = ["MAX_CANDIDATES", "binding_skeleton", "candidates", "free_simulation_ids", "guess_values"]

MAX_CANDIDATES = 8  # per quantity, the ones that fit first; the count of the others is said
# a protection's own fields, not a quantity's
_PROTECTION = re.compile(r"(?i)(crc|counter|cnt$|chksum|checksum|alive|_ac$)")


def free_simulation_ids(db: Database) -> dict[str, int]:
    """By message of the simulation database that ``db`` lacks, an ID it leaves free: the simulation database's own
    where free, else the highest free 11-bit ID (the matrix's IDs and its diagnostic request/response IDs taken)."""
    simulation = cantools.database.load_string(SIM_DATABASE.read_text(encoding="utf-8"), "dbc", strict=True)
    assert isinstance(simulation, Database)
    taken = {m.frame_id for m in db.messages}
    attributes = db.dbc.attributes if db.dbc is not None else {}
    taken |= {int(attributes[a].value) for a in ("DiagRequestId", "DiagResponseId") if a in attributes}
    names = {m.name for m in db.messages}
    ids: dict[str, int] = {}
    for message in sorted(simulation.messages, key=lambda m: m.name != "SIM_SYNC"):
        if message.name in names:
            continue
        frame_id = message.frame_id if message.frame_id not in taken else max(set(range(0x800)) - taken)
        ids[message.name] = frame_id
        taken.add(frame_id)
    return ids


def candidates(db: Database, quantity: str) -> list[tuple[Message, Signal, str, list[str]]]:
    """(message, signal, unit, why it cannot carry ``quantity``) of every signal of ``db`` whose unit converts to
    the quantity's (a protection's counter or CRC left out): the ones that can first, the narrowest range first."""
    spec = QUANTITIES[quantity]
    found = []
    for message in db.messages:
        for signal in message.signals:
            unit = signal.unit or ""
            converted = conversion(unit, spec.unit)
            if converted is None or _PROTECTION.search(signal.name) or signal.is_multiplexer:
                continue
            lo, hi = (converted[0] * v + converted[1] for v in signal_range(signal))
            found.append((message, signal, unit, signal_fit(quantity, signal, *converted), abs(hi - lo)))
    found.sort(key=lambda c: (bool(c[3]), c[4]))
    return [c[:4] for c in found]


def _line(quantity: str, message: Message, signal: Signal, unit: str, why: list[str]) -> str:
    cycle = f"{message.cycle_time} ms" if message.cycle_time else "no cycle time"
    sender = f", from {', '.join(message.senders)}" if message.senders else ""
    note = f"{unit or 'no unit'}, {cycle}{sender}" + (f": carries {'; '.join(why)}" if why else "")
    return f'#{quantity} = "{message.name}.{signal.name}"  # {note}'


def guess_values(quantity: str, choices: dict[int, str]) -> dict[str, str]:
    """By name of the TCU's (``quantity``'s numbers, :func:`~.binding.shipped_numbers`), the name of the value table
    ``choices`` that is the same when case and punctuation are left out, or else the one sharing the longest start
    with it (four letters at least, no other as long); ``"?"`` where none is, or where the name went to another."""
    def plain(name: str) -> str:
        return re.sub(r"[^a-z0-9]", "", name.lower())

    def shared(a: str, b: str) -> int:
        n = 0
        while n < min(len(a), len(b)) and a[n] == b[n]:
            n += 1
        return n

    theirs = [str(name) for name in choices.values()]
    found: dict[str, str] = {}
    for ours in shipped_numbers(quantity):
        same = [t for t in theirs if plain(t) == plain(ours)]
        if not same:
            scores = {t: shared(plain(t), plain(ours)) for t in theirs}
            best = max(scores.values(), default=0)
            same = [t for t, n in scores.items() if n == best] if best >= 4 else []
        found[ours] = same[0] if len(same) == 1 and same[0] not in found.values() else "?"
    return found


def _values_line(quantity: str, message: Message, signal: Signal) -> str:
    """The entry with ``values`` of a candidate with a value table: the TCU's names, the table's guessed for them."""
    choices = {int(number): str(name) for number, name in (signal.choices or {}).items()}
    guessed = guess_values(quantity, choices)
    listed = ", ".join(f'{ours} = "{theirs}"' for ours, theirs in guessed.items())
    table = ", ".join(f"{number} {name}" for number, name in sorted(choices.items()))
    if all(choices.get(number) == guessed[ours] for ours, number in shipped_numbers(quantity).items()):
        note = "numbered as the TCU numbers them: values may stay out"
    elif "?" in guessed.values():
        note = "give the table's name of each \"?\"" + (", check the ones guessed" if set(guessed.values()) != {"?"}
                                                         else "")
    else:
        note = "the names guessed: check each"
    return (f'#{quantity} = {{ signal = "{message.name}.{signal.name}", values = {{ {listed} }} }}  '
            f"# its values: {table}; {note}")


def binding_skeleton(db: Database, source: str) -> str:
    """The skeleton's TOML text for the database ``db`` read from ``source`` (the name the text cites)."""
    ids = free_simulation_ids(db)
    extended = copy.deepcopy(db)
    problems: list[str] = []
    add_simulation(source, {"ids": ids}, extended, problems)
    assert not problems, problems
    required = [q for q, spec in QUANTITIES.items() if spec.required]
    out = [
        f"# A binding for {source}, from dsg-hil binding init. Under each quantity of the plant, commented out,",
        "# the database's signals that can carry its range and resolution, the narrowest range first.",
        "# Uncomment one per quantity you map, list its message in send or read, name the lock-step echo, then:",
        f"#   dsg-hil binding check {source} THIS_FILE",
        f"# The plant needs {', '.join(required)} (the TCU's commands and state);",
        "# every other quantity may stay unmapped, and the plant then does not send it (ecu-stub, as the other end,",
        "# needs every sensor and driver quantity).",
        "",
        "send = []  # the messages the plant sends (its sensors' frames, the truth), in the order of a period's frames",
        "read = []  # the messages it reads (the TCU's)",
        "",
    ]
    if ids:
        listed = ", ".join(f"{name} = 0x{frame_id:03X}" for name, frame_id in ids.items())
        out += ["[simulation]  # the simulation database's messages, on IDs the matrix leaves free",
                f"ids = {{ {listed} }}", ""]
    echoes = [f"{m.name}.{s.name}" for m in db.messages for s in m.signals
              if re.search(r"(?i)echo|sync|step|tick", s.name) and not _PROTECTION.search(s.name)
              and s.length >= 8 and m.name not in ids]
    out += ["[lockstep]", 'tick = "SIM_SYNC.Tick"',
            'echo = "MESSAGE.Signal"  # the TCU\'s echo of the tick\'s low byte, in its command message (8 bits)'
            + (f"; maybe {', '.join(echoes[:4])}" if echoes else ""), "", "[quantities]"]
    for direction, title in (("send", "the plant sends"), ("read", "the plant reads (the TCU's frames)")):
        out += [f"# ---- {title} ----"]
        for quantity, spec in QUANTITIES.items():
            if spec.direction != direction:
                continue
            need = " (required)" if spec.required else ""
            unit = "" if spec.unit == "1" else f" {spec.unit}"
            out.append(f"# {quantity}{need}: {spec.doc}; {spec.lo:.6g}..{spec.hi:.6g}{unit} in steps of "
                       f"{spec.resolution:.6g}{unit} or finer")
            # the simulation database's signals for the truth only, its tick for none
            truth = spec.doc.startswith("truth:")
            found = [c for c in candidates(extended, quantity) if c[0].name != "SIM_SYNC"
                     and (truth or c[0].name not in ids)]
            fit = [c for c in found if not c[3]]
            if not found:
                out.append(f"#   (no signal converts to {spec.unit})")
            elif not fit:
                out.append("#   (no signal can carry it; the closest:)")
            shown = fit[:MAX_CANDIDATES] if fit else found[:3]
            for message, signal, unit, why in shown:
                out.append(_line(quantity, message, signal, unit, why))
                if quantity in VALUED and len(signal.choices or ()) >= len(shipped_numbers(quantity)):
                    out.append(_values_line(quantity, message, signal))
            if len(fit) > len(shown):
                out.append(f"#   ... and {len(fit) - len(shown)} more that can carry it")
    return "\n".join(out) + "\n"
