"""``dsg-hil completion bash``: the script completes commands and each command's options, as bash runs it."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from dsg_hil.cli import COMMANDS
from dsg_hil.cli.completion_cmd import command_options


def complete(*words: str) -> list[str]:
    """What bash offers after ``words`` (the last one being completed), with the script sourced."""
    script = subprocess.run([sys.executable, "-m", "dsg_hil", "completion", "bash"], capture_output=True, text=True,
                            check=True).stdout
    line = " ".join(f"'{w}'" for w in words)
    shell = f"{script}\nCOMP_WORDS=({line}); COMP_CWORD={len(words) - 1}; _dsg_hil\n" \
        "printf '%s\\n' \"${COMPREPLY[@]}\""
    return subprocess.run(["bash", "-c", shell], capture_output=True, text=True, check=True).stdout.split()


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash here")
def test_bash_completes_commands_and_their_options():
    assert complete("dsg-hil", "re") == ["report"]
    assert set(complete("dsg-hil", "")) >= set(COMMANDS)
    assert complete("dsg-hil", "run", "--cal") == ["--calibration"]
    assert complete("dsg-hil", "plant", "--qu") == ["--quiet"]
    assert complete("dsg-hil", "dbc", "--cal") == []  # not an option of dbc


def test_the_options_are_read_from_every_commands_parser():
    options = command_options()
    assert list(options) == list(COMMANDS)
    assert {"--set", "--params", "--calibration", "--fault", "--log"} <= set(options["run"])
    assert "--from-log" in options["report"] and "--from-log" not in options["run"]
