"""One error tree (dsg_hil.common.errors): every exception class of dsg-hil and ecu-stub is in it, drawn in the
module's docstring, and each branch has its exit status."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import pytest

import dsg_hil
import ecu_stub
from dsg_hil.cli import main
from dsg_hil.common import errors
from dsg_hil.common.cli import Terminated
from dsg_hil.common.errors import (
    EXIT_BAD_INPUT,
    EXIT_OUT_OF_BAND,
    EXIT_RUN_FAILED,
    DsgHilError,
    InputError,
    ResultError,
    RunError,
    exit_code,
)

SIGNALS = {Terminated}  # BaseException like KeyboardInterrupt: never caught by 'except Exception'
BRANCHES = {InputError: EXIT_BAD_INPUT, RunError: EXIT_RUN_FAILED, ResultError: EXIT_OUT_OF_BAND}


def defined_exceptions() -> list[type[BaseException]]:
    """Every exception class defined in a module of dsg_hil or ecu_stub (each module imported; not __main__)."""
    found = []
    for package in (dsg_hil, ecu_stub):
        names = [package.__name__] + [m.name for m in pkgutil.walk_packages(package.__path__, package.__name__ + ".")
                                      if not m.name.endswith("__main__")]
        for name in names:
            module = importlib.import_module(name)
            found += [obj for _, obj in inspect.getmembers(module, inspect.isclass)
                      if issubclass(obj, BaseException) and obj.__module__ == name]
    return found


EXCEPTIONS = defined_exceptions()


def test_the_walk_finds_the_errors_of_every_part():
    """The walk sees classes from the kernel, the protocol, the plant's runner, the TCU and the vcan tool."""
    names = {cls.__name__ for cls in EXCEPTIONS}
    assert {"DsgHilError", "ProtocolError", "ParameterError", "ScenarioError", "PeerLost", "CalibrationError",
            "VcanError", "Terminated"} <= names


@pytest.mark.parametrize("cls", EXCEPTIONS, ids=lambda cls: f"{cls.__module__}.{cls.__name__}")
def test_every_exception_is_in_the_tree_and_drawn(cls):
    assert cls in SIGNALS or issubclass(cls, DsgHilError), f"{cls} is outside the tree"
    assert cls in SIGNALS or cls is DsgHilError or any(issubclass(cls, branch) for branch in BRANCHES)
    assert f" {cls.__name__} " in errors.__doc__, f"{cls.__name__} is missing from the tree in the docstring"


@pytest.mark.parametrize("cls", [cls for cls in EXCEPTIONS if cls not in SIGNALS], ids=lambda cls: cls.__name__)
def test_each_error_exits_with_its_branch_status(cls):
    branch = next((b for b in BRANCHES if issubclass(cls, b)), DsgHilError)
    error = cls.__new__(cls)  # without __init__: some take more than a message
    assert exit_code(error) == BRANCHES.get(branch, EXIT_RUN_FAILED)


def test_branch_statuses_and_their_standard_bases():
    assert (exit_code(InputError("x")), exit_code(RunError("x")), exit_code(ResultError("x"))) == (2, 1, 3)
    assert exit_code(DsgHilError("x")) == exit_code(KeyError("a bug")) == 1  # unexpected errors: 1
    assert issubclass(InputError, ValueError) and issubclass(RunError, RuntimeError)
    assert not issubclass(Terminated, Exception)  # 'except Exception' in a run does not swallow SIGTERM


def test_a_result_out_of_band_is_exit_3_with_one_error_line(capsys):
    """ResultError where a result is out of its band: 'dsg-hil dbc' at a bit rate the frames overload."""
    assert main(["dbc", "--bitrate", "10000"]) == EXIT_OUT_OF_BAND
    captured = capsys.readouterr()
    assert "total at 10 kbit/s" in captured.out  # the table is printed all the same
    assert captured.err.splitlines() == ["error: bus load 945.0% at 10 kbit/s above the limit 30%"]
