"""MkDocs hook: the reference pages made from the code at build time, so they cannot drift from it.

Each page is read from what the program itself uses: the argparse parsers of every command, the DBC the codec
loads, the shipped ``params.toml`` with each value's source, the exit codes and error tree of
``dsg_hil.common.errors``, the fault kinds of ``dsg_hil.protocol.faults``, the JSON the ``bench/`` scripts
write, and the DIDs and DTCs of ``dsg_hil/data/diag.toml`` as ``dsg_hil.protocol.diag`` reads it (the
diagnostics guide's tables, :data:`MARKERS`). ``mkdocs.yml`` lists this module under ``hooks``; nothing here is
copied into the site.
"""

from __future__ import annotations

import argparse
import importlib
import json
import re
import shlex
import textwrap
import tomllib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from importlib.resources import files
from pathlib import Path
from typing import Any

__all__ = ["MARKERS", "PAGES", "bad_input_table", "bench_page", "cli_page", "codes_page", "dbc_page", "did_table",
           "dtc_table", "figures", "nested_lists", "on_files", "on_page_content", "on_page_markdown", "params_page",
           "plain_roles", "snapshot_dids"]

ROOT = Path(__file__).resolve().parents[2]


def _cell(text: object) -> str:
    """A Markdown table cell: one line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _plain(text: object) -> str:
    """Text from the code shown as it is: brackets escaped (``[-o FILE]`` is no Markdown link)."""
    return _cell(text).replace("[", "\\[").replace("]", "\\]")


def _table(head: list[str], rows: list[list[object]]) -> list[str]:
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head),
            *("| " + " | ".join(_cell(c) for c in row) + " |" for row in rows)]


# -- command lines ---------------------------------------------------------------------------------------------

class _Parsed(Exception):
    """Carries the parser a command's ``_parse_args`` built (raised instead of parsing)."""

    def __init__(self, parser: argparse.ArgumentParser) -> None:
        super().__init__(parser.prog)
        self.parser = parser


@contextmanager
def _capturing() -> Iterator[None]:
    original = argparse.ArgumentParser.parse_args

    def capture(self: argparse.ArgumentParser, *args: Any, **kwargs: Any) -> Any:
        raise _Parsed(self)

    argparse.ArgumentParser.parse_args = capture  # type: ignore[method-assign]
    try:
        yield
    finally:
        argparse.ArgumentParser.parse_args = original  # type: ignore[method-assign]


def _parser_of(parse_args: Callable[[list[str] | None], Any]) -> argparse.ArgumentParser:
    """The parser a command line's ``_parse_args`` builds, as its ``main`` uses it."""
    with _capturing():
        try:
            parse_args([])
        except _Parsed as parsed:
            return parsed.parser
    raise RuntimeError(f"{parse_args} parsed nothing")


def parsers() -> dict[str, argparse.ArgumentParser]:
    """Every command line by how a user types it: ``dsg-hil``'s subcommands, ``ecu-stub``, the identification."""
    from dsg_hil.cli import COMMANDS

    sub = argparse.ArgumentParser(prog="dsg-hil").add_subparsers()
    for module, _ in COMMANDS.values():
        importlib.import_module(f"dsg_hil.cli.{module}").add_subparser(sub)
    found = {f"dsg-hil {name}": parser for name, parser in sub.choices.items()}
    found["ecu-stub"] = _parser_of(importlib.import_module("ecu_stub.cli")._parse_args)
    found["python -m ecu_stub.identify"] = _parser_of(importlib.import_module("ecu_stub.identify")._parse_args)
    return found


def _option_rows(parser: argparse.ArgumentParser) -> list[list[object]]:
    formatter = parser._get_formatter()
    rows: list[list[object]] = []
    for action in parser._actions:
        if action.help == argparse.SUPPRESS:
            continue
        names = ", ".join(action.option_strings) or str(action.metavar or action.dest)
        if action.option_strings and action.nargs != 0:
            names += f" {formatter._format_args(action, action.dest.upper())}"
        if isinstance(action, argparse._SubParsersAction):
            continue
        rows.append([f"`{names}`", _plain(formatter._expand_help(action)) if action.help else ""])
    return rows


def cli_page() -> str:
    """Every command and option, from the parsers the commands run."""
    from dsg_hil.cli import COMMANDS

    lines = ["# Command lines", "",
             "Generated from the argparse parsers of `dsg-hil`, `ecu-stub` and `python -m ecu_stub.identify`.",
             "Every command also takes `--help` and `--debug` (a traceback on errors).", "",
             *_table(["command", "what it does"],
                     [[f"[`dsg-hil {name}`](#dsg-hil-{name})", help_] for name, (_, help_) in COMMANDS.items()]),
             ""]
    for name, parser in parsers().items():
        lines += [f"## `{name}` {{#{re.sub('[^a-z0-9]+', '-', name).strip('-')}}}", "",
                  _plain(parser.description or ""), "", "```text", parser.format_usage().strip(), "```", "",
                  *_table(["option", "meaning"], _option_rows(parser)), ""]
    return "\n".join(lines)


# -- the CAN contract ------------------------------------------------------------------------------------------

def dbc_page() -> str:
    """Every message and signal of the shipped DBC: IDs, senders, cycle times, units, ranges, protection."""
    from dsg_hil.protocol import e2e
    from dsg_hil.protocol.codec import load_dbc

    db = load_dbc()  # the shipped DBC, as the plant and ecu-stub load it
    lines = ["# DBC messages and signals", "",
             "Generated from `dbc/dsg_hil.dbc`, the file the codec loads. Classic CAN, 11-bit IDs.",
             "Each message's `Counter` and `CRC` carry the end-to-end protection ([the CAN contract](can.md)).", "",
             *_table(["ID", "message", "sender", "cycle", "bytes", "signals"],
                     [[f"0x{m.frame_id:03X}", f"[{m.name}](#{m.name.lower()})", ", ".join(m.senders),
                       f"{m.cycle_time} ms" if m.cycle_time else "-", m.length, len(m.signals)]
                      for m in db.messages]), "",
             "## End-to-end protection", "",
             # the scheme as the protection module states it (its docstring, rst literals as Markdown code)
             (e2e.__doc__ or "").replace("``MAX_DELTA``", str(e2e.MAX_DELTA)).replace("``", "`"),
             "Each message's CRC byte and counter range, as the protection reads them from its signals:", "",
             *_table(["message", "CRC byte", "counter values"],
                     [[m.name, (p := e2e.Protection.of(m)).crc_byte, f"0 .. {p.counter_modulus - 1}"]
                      for m in db.messages]), ""]
    for m in db.messages:
        lines += [f"## {m.name} {{#{m.name.lower()}}}", "",
                  f"ID 0x{m.frame_id:03X}, sent by {', '.join(m.senders)}, every "
                  f"{m.cycle_time} ms, {m.length} bytes." if m.cycle_time else
                  f"ID 0x{m.frame_id:03X}, sent by {', '.join(m.senders)}, {m.length} bytes.", ""]
        if m.comment:
            lines += [_plain(m.comment), ""]
        rows: list[list[object]] = []
        for s in m.signals:
            values = "; ".join(f"{k} = {v}" for k, v in s.choices.items()) if s.choices else ""
            rows.append([f"`{s.name}`", f"{s.start}\\|{s.length}", s.scale, s.offset,
                         f"{s.minimum} .. {s.maximum}", s.unit or "-",
                         _plain(" ".join(filter(None, [s.comment, values])))])
        lines += _table(["signal", "start\\|bits", "scale", "offset", "range", "unit", "meaning"], rows) + [""]
    return "\n".join(lines)


# -- parameters ------------------------------------------------------------------------------------------------

def _entries(table: dict[str, Any], prefix: str = "") -> Iterator[tuple[str, dict[str, Any]]]:
    for key, value in table.items():
        if isinstance(value, dict) and "value" in value:
            yield prefix + key, value
        elif isinstance(value, dict):
            yield from _entries(value, f"{prefix}{key}.")


def params_page() -> str:
    """Every model parameter of the shipped ``params.toml``: value, unit, and where it comes from."""
    data = tomllib.loads((files("dsg_hil") / "data" / "params.toml").read_text(encoding="utf-8"))
    entries = list(_entries({k: v for k, v in data.items() if k != "meta"}))
    counts = {s: sum(e["source"] == s for _, e in entries) for s in ("paper", "assumed", "calibrated")}
    lines = ["# Parameters", "",
             "Generated from `dsg_hil/data/params.toml`, the file the plant loads. SI units, temperatures in °C.",
             f"{len(entries)} values: {counts['paper']} from the paper, {counts['assumed']} assumed, "
             f"{counts['calibrated']} calibrated.",
             "`dsg-hil params` prints the same table; [Parameters](../how-to/parameters.md) says how to change "
             "them.", ""]
    sections: dict[str, list[tuple[str, dict[str, Any]]]] = {}
    for key, entry in entries:
        sections.setdefault(key.rsplit(".", 1)[0], []).append((key, entry))
    for section, items in sections.items():
        lines += [f"## {section}", "",
                  *_table(["key", "value", "unit", "source", "where from"],
                          [[f"`{key}`", entry["value"], entry.get("unit", ""), entry["source"],
                            _plain(entry.get("ref") or entry.get("why") or entry.get("target") or "")]
                           for key, entry in items]), ""]
    return "\n".join(lines)


# -- exit codes, errors, fault kinds ----------------------------------------------------------------------------

def codes_page() -> str:
    """Exit codes and the error tree from ``dsg_hil.common.errors``; fault kinds from the fault parser's table."""
    from dsg_hil.common import errors
    from dsg_hil.protocol.faults import spec

    codes = sorted((value, name) for name, value in vars(errors).items() if name.startswith("EXIT_"))
    tree = textwrap.dedent((errors.__doc__ or "").split("::", 1)[1].split("\n\nAny other", 1)[0].strip("\n"))
    lines = ["# Exit codes, errors and fault kinds", "",
             "Generated from `dsg_hil.common.errors` and `dsg_hil.protocol.faults`, the tables the programs use.",
             "", "## Exit codes", "",
             *_table(["status", "constant"], [[value, f"`{name}`"] for value, name in codes]), "",
             "## The error tree", "",
             "Every error dsg-hil and ecu-stub raise on purpose, with its exit status "
             "(the module in brackets defines it):", "", "```text", tree.rstrip(), "```", "",
             "Any other exception that ends a command is a bug: exit 1.", "",
             "## Fault kinds", "",
             "The kinds `--fault` and a scenario's `[[fault]]` tables accept "
             f"(signal faults, which target `MESSAGE.Signal`: {', '.join(sorted(spec.SIGNAL_KINDS))}):", "",
             *_table(["kind", "what happens to the frame"], [[f"`{k}`", _plain(v)] for k, v in spec.KINDS.items()]), ""]
    return "\n".join(lines)


# -- performance -----------------------------------------------------------------------------------------------

def _rounded(value: Any) -> Any:
    """Floats to 4 significant digits (a bench's figures are no more precise than that), inside lists and tables."""
    if isinstance(value, float):
        return float(f"{value:.4g}")
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_rounded(v) for v in value]
    return value


def _value(value: object) -> str:
    """A figure as the table shows it: numbers (4 significant digits) and words as they are, lists and tables as
    compact JSON."""
    value = _rounded(value)
    if isinstance(value, dict | list):
        return json.dumps(value, ensure_ascii=False, separators=(", ", ": "))
    return f"{value:g}" if isinstance(value, float) and abs(value) < 1e6 and value == int(value) else str(value)


def _rows_table(rows: list[dict[str, Any]], first: str = "") -> list[str]:
    """Records of the same kind (a bench's cases) as one table, a column per key."""
    keys = [k for k in dict.fromkeys(k for row in rows for k in row) if k != first]
    head = ([first] if first else []) + keys
    return _table(head, [([row.get(first, "")] if first else []) + [_value(row.get(k, "")) for k in keys]
                         for row in rows])


def _is_records(value: object) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _is_named_records(value: object) -> bool:
    return isinstance(value, dict) and bool(value) and all(isinstance(v, dict) for v in value.values())


def _flat(results: dict[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    for key, value in results.items():
        if isinstance(value, dict) and not _is_named_records(value):
            yield from _flat(value, f"{prefix}{key}.")
        else:
            yield prefix + key, value


def figures(results: object) -> list[str]:
    """A bench's JSON as Markdown: its single figures in one table (nested keys dotted), its lists of cases (a list
    of objects, or an object of objects by name) each a table of their own."""
    if _is_records(results):
        return [*_rows_table(results), ""]  # type: ignore[arg-type]
    if not isinstance(results, dict):
        return [_value(results), ""]
    single: list[list[object]] = []
    tables: list[str] = []
    for key, value in _flat(results):
        if _is_records(value):
            tables += [f"**{key}**", "", *_rows_table(value), ""]
        elif _is_named_records(value):
            tables += [f"**{key}**", "", *_rows_table([{"name": n, **v} for n, v in value.items()], "name"), ""]
        else:
            single.append([key, _value(value)])
    return ([*_table(["figure", "value"], single), ""] if single else []) + tables


def bench_page() -> str:
    """The measured figures: every ``bench/results/*.json`` with its date, machine and command."""
    found = sorted((ROOT / "bench" / "results").glob("*.json"))
    lines = ["Generated from the JSON files in `bench/results/`, kept by `python bench/record.py NAME -- COMMAND`.",
             ""]
    if not found:
        lines += ["No benchmark result is recorded in `bench/results/` yet.", ""]
    for path in found:
        data = json.loads(path.read_text(encoding="utf-8"))
        took = f"{data['wall_s']:g} s" if isinstance(data.get("wall_s"), int | float) else "-"
        script = re.search(r"bench/(\w+\.py)", str(data.get("command", "")))
        what = _cell(_first_line(ROOT / "bench" / script.group(1))) if script else ""
        lines += [f"### {path.stem}", "", what, "",
                  *_table(["date", "machine", "command", "took"],
                          [[data.get("date", "?"), data.get("machine", "?"), f"`{data.get('command', '?')}`", took]]),
                  ""]
        results = data.get("results", {k: v for k, v in data.items() if k not in ("date", "machine", "command")})
        lines += figures(results)
    scripts = sorted((ROOT / "bench").glob("*.py"))
    lines += ["### The scripts", "", *_table(["script", "what it measures"],
                                          [[f"`bench/{p.name}`", _first_line(p)] for p in scripts]), ""]
    return "\n".join(lines)


# -- bad input -------------------------------------------------------------------------------------------------

def bad_input_table() -> str:
    """Every scripted bad-input case the tests run (``CASES`` of ``tests/cli/test_bad_input.py``): the command line,
    what is bad, and what its one error line says."""
    import sys

    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    cases = importlib.import_module("tests.cli.test_bad_input")
    program = {"dsg-hil": "dsg-hil", "ecu-stub": "ecu-stub", "identify": "python -m ecu_stub.identify"}
    rows: list[list[object]] = []
    for i, (prog, argv, bad, form, needle) in enumerate(cases.CASES, 1):
        line = " ".join([program[prog], *(shlex.quote(a) for a in argv)])
        said = f"`{needle}`" if form == cases.ERROR else f"usage, then `PROG: error: {needle}`"
        rows.append([i, f"`{line}`", "an option" if bad == "option" else "a file", said])
    return "\n".join(_table(["#", "command line", "bad", "the error line says"], rows))


# -- diagnostics -----------------------------------------------------------------------------------------------

def did_table() -> str:
    """Every DID of ecu-stub's description, one row per field (a text DID: one row), as the server encodes it."""
    from dsg_hil.protocol.diag import load_description

    rows: list[list[object]] = []
    for did in load_description().dids.values():
        if did.ascii_length:
            rows.append([f"0x{did.id:04X}", f"`{did.name}`", "-", f"ASCII, {did.ascii_length} bytes", "-", "-", "-"])
        for field in did.fields:
            rows.append([f"0x{did.id:04X}", f"`{did.name}`", f"`{field.name}`", field.type, f"{field.scale:g}",
                         f"{field.offset:g}", field.unit])
    return "\n".join(_table(["DID", "name", "field", "type", "scale", "offset", "unit"], rows))


def dtc_table() -> str:
    """Every DTC of ecu-stub's description: code, number, what sets it, its debounce."""
    from dsg_hil.protocol.diag import load_description

    rows: list[list[object]] = [[f"`{d.code}`", f"0x{d.number:06X}", f"`{d.name}`", f"`{d.monitor}`", d.debounce,
                                 f"{10 * d.debounce} ms", _plain(d.text)] for d in load_description().dtcs]
    head = ["code", "number", "name", "monitor", "debounce [periods]", "debounce time", "meaning"]
    return "\n".join(_table(head, rows))


def snapshot_dids() -> str:
    """The DIDs of every freeze frame, in their order."""
    from dsg_hil.protocol.diag import load_description

    description = load_description()
    return ", ".join(f"0x{did:04X} `{description.dids[did].name}`" for did in description.snapshot)


def _first_line(path: Path) -> str:
    import ast

    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    return doc.split("\n\n", 1)[0]


PAGES: dict[str, Callable[[], str]] = {
    "reference/cli.md": cli_page,
    "reference/dbc.md": dbc_page,
    "reference/params.md": params_page,
    "reference/codes.md": codes_page,
}
BENCH_MARKER = "<!-- bench-results -->"  # where performance.md shows the recorded benchmark JSON
# where a page shows a table made from the code: marker -> what replaces it
MARKERS: dict[str, Callable[[], str]] = {BENCH_MARKER: bench_page, "<!-- bad-input-cases -->": bad_input_table,
                                         "<!-- diag-dids -->": did_table, "<!-- diag-dtcs -->": dtc_table,
                                         "<!-- diag-snapshot -->": snapshot_dids}


def on_files(files: Any, config: Any) -> Any:
    """MkDocs event: add the generated pages to the site's files."""
    from mkdocs.structure.files import File

    for uri, make in PAGES.items():
        files.append(File.generated(config, uri, content=make()))
    return files


def nested_lists(markdown: str) -> str:
    """Lists written as GitHub reads them, made what Python-Markdown reads: a blank line before a list that
    follows a paragraph, and nested items indented four spaces a level rather than two (outside code blocks;
    continuation lines stay lazy continuations)."""
    out: list[str] = []
    fenced = in_list = False
    for line in markdown.split("\n"):
        if line.lstrip().startswith("```"):
            fenced = not fenced
        if fenced or not line.strip():
            out.append(line)
            continue
        if re.match(r"^(?:[-*]|\d+\.) ", line):
            if not in_list and out and out[-1].strip():
                out.append("")
            in_list = True
        elif not line.startswith(" ") and out and not out[-1].strip():
            in_list = False
        marker = re.match(r"^((?:  )+)(?:[-*]|\d+\.) ", line)
        if marker and len(marker.group(1)) % 4:
            line = marker.group(1) * 2 + line[len(marker.group(1)):]
        out.append(line)
    return "\n".join(out)


ROLE = re.compile(r":(?:class|func|meth|mod|attr|data|exc|obj):<code>(~?)([\w.]+)</code>")


def plain_roles(html: str) -> str:
    """The docstrings' Sphinx roles (``:class:`~a.b.C```) as the code they name (``C``; the full path without ~)."""
    return ROLE.sub(lambda m: f"<code>{m.group(2).rsplit('.', 1)[-1] if m.group(1) else m.group(2)}</code>", html)


def on_page_content(html: str, page: Any, config: Any, files: Any) -> str:
    """MkDocs event: the API page's docstrings without Sphinx role markup."""
    return plain_roles(html)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """MkDocs event: nested lists as GitHub shows them; the tables made from the code (:data:`MARKERS`) where a page
    asks."""
    markdown = nested_lists(markdown)
    for marker, make in MARKERS.items():
        if marker in markdown:
            markdown = markdown.replace(marker, make())
    return markdown
