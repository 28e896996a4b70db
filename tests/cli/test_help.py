"""What ``--help`` and the README tell a user is true: no argparse escapes, examples the command accepts, one
statement of the fault clock, no internal issue numbers, the default duration of the shipped scenario."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from dsg_hil.cli import COMMANDS, main
from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.faults import check_faults, parse_fault
from dsg_hil.sim.scenario import load_scenario
from ecu_stub.cli import main as ecu_stub_main

README = Path(__file__).resolve().parents[2] / "docs" / "how-to" / "interfaces.md"  # a plant's first lines


def _help(entry, argv: list[str], capsys) -> str:
    """The text ``entry(argv + ['--help'])`` prints, in one line (argparse wraps at the terminal's width)."""
    with pytest.raises(SystemExit) as exc:
        entry([*argv, "--help"])
    assert exc.value.code == 0
    return " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("argv", [[], *([name] for name in COMMANDS)], ids=lambda argv: " ".join(argv) or "dsg-hil")
def test_help_has_no_argparse_escapes(argv, capsys):
    text = _help(main, argv, capsys)
    assert "%%" not in text and "%(" not in text


def test_ecu_stub_help_has_no_argparse_escapes(capsys):
    text = _help(ecu_stub_main, [], capsys)
    assert "%%" not in text and "%(" not in text


def test_dbc_help_states_the_load_limit(capsys):
    from dsg_hil.cli.dbc_cmd import LOAD_LIMIT  # noqa: PLC0415

    assert f"Exit 3 above {LOAD_LIMIT:.0%}." in _help(main, ["dbc"], capsys)


def test_ecu_stub_fault_examples_are_accepted(capsys):
    """Every example in ecu-stub's ``--fault`` help parses and changes the TCU's frames (ecu-stub rejects the
    plant's with 'changes the plant's frames')."""
    text = _help(ecu_stub_main, [], capsys)
    examples = re.findall(r"'([a-z_]+:[^']+)'", text.split("--fault SPEC", 2)[2])
    assert len(examples) >= 2
    by_side = check_faults([parse_fault(example) for example in examples], load_dbc())
    assert not by_side["plant"] and len(by_side["tcu"]) == len(examples)


def test_ecu_stub_config_context_is_the_tcus(capsys):
    """The TCU never picks a multicast group: it joins the plant's."""
    text = _help(ecu_stub_main, [], capsys)
    assert "picks a multicast group" not in text and "options 'dsg-hil plant' prints" in text


def test_bridge_help_states_one_fault_clock(capsys):
    text = _help(main, ["bridge"], capsys)
    assert "since the bridge started" in text
    assert "sender's seconds" not in text and "simulated in lockstep" not in text


def test_params_mention_no_internal_issue(capsys):
    assert main(["params"]) == 0
    assert not re.search(r"\bissue \d", capsys.readouterr().out)


def test_readme_plant_line_shows_the_default_duration():
    """The interfaces guide's example of 'dsg-hil plant' prints the shipped scenario's duration."""
    shown = re.findall(r"^plant: .*?, (\d+(?:\.\d+)?) s, ", README.read_text(encoding="utf-8"), re.MULTILINE)
    assert shown and all(float(s) == load_scenario().duration_s for s in shown)


def test_diag_examples_are_accepted(capsys):
    """Every example in ``dsg-hil diag --help`` parses, and the DIDs it reads are the shipped description's."""
    import argparse  # noqa: PLC0415
    import shlex  # noqa: PLC0415

    from dsg_hil.cli.diag_cmd import add_subparser, resolve_dids  # noqa: PLC0415
    from dsg_hil.protocol.diag import load_description  # noqa: PLC0415

    with pytest.raises(SystemExit):
        main(["diag", "--help"])
    examples = [shlex.split(line) for line in capsys.readouterr().out.splitlines()
                if line.strip().startswith("dsg-hil diag ")]
    assert len(examples) >= 5 and {argv[2] for argv in examples} == {"dtc", "read", "clear"}
    parser = argparse.ArgumentParser(prog="dsg-hil")
    add_subparser(parser.add_subparsers())
    for argv in examples:
        args = parser.parse_args(argv[1:])
        if args.description is None:
            assert len(resolve_dids(args.did, load_description(), "diag.toml")) >= 1
