"""The package's exceptions and exit codes, one hierarchy (after python-can's CanError and cantools' Error).

Here in the protocol layer so that ecu-stub, which may import only :mod:`dsg_hil.protocol`, shares them;
:mod:`dsg_hil.errors` re-exports them.

* :class:`InputError` (a ``ValueError``): a bad file, key, option or value; nothing ran. Exit 2.
* :class:`RunError` (a ``RuntimeError``): the run could not go on (peer lost, bus gone ...). Exit 1.
* :class:`ResultError`: the run finished but its result is outside its band. Exit 3.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

EXIT_OK, EXIT_RUN_FAILED, EXIT_BAD_INPUT, EXIT_OUT_OF_BAND = 0, 1, 2, 3
EXIT_SIGINT, EXIT_SIGTERM = 128 + signal.SIGINT, 128 + signal.SIGTERM  # as a shell reports a killed process


class DsgHilError(Exception):
    """Base of every error dsg-hil and ecu-stub raise on purpose."""

    exit_code = EXIT_RUN_FAILED


class InputError(DsgHilError, ValueError):
    """Bad input: the message names the file, key or option and what is wrong."""

    exit_code = EXIT_BAD_INPUT


class RunError(DsgHilError, RuntimeError):
    """The run failed (e.g. the peer was lost)."""

    exit_code = EXIT_RUN_FAILED


class ResultError(DsgHilError):
    """The run's result is outside its band."""

    exit_code = EXIT_OUT_OF_BAND


def exit_code(exc: BaseException) -> int:
    """The exit status for an error that ends a command: the hierarchy's, else 1 (an unexpected error)."""
    return exc.exit_code if isinstance(exc, DsgHilError) else EXIT_RUN_FAILED


def read_input_file(path: Path, what: str, error: type[InputError]) -> str:
    """The UTF-8 text of an input file (scenario, parameters, calibration), or one ``error`` naming the file."""
    try:
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"{path}: cannot read {what} ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not UTF-8 text (byte {exc.start}): not a {what} TOML") from None


def check_output_path(option: str, path: str | None, directory: bool = False) -> None:
    """Fail before the run, not after it, when ``path`` (a file; ``directory``: a directory to write into)
    cannot be written: a directory (a file), or a parent that is not a writable directory (missing parents
    are created at the end: the nearest existing one counts)."""
    if path is None:
        return
    target = Path(path)
    if directory and target.exists():
        if not target.is_dir() or not os.access(target, os.W_OK | os.X_OK):
            raise InputError(f"{option} {path}: not a writable directory")
        return
    if not directory and target.is_dir():
        raise InputError(f"{option} {path}: is a directory")
    parent = target.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{option} {path}: {parent} is not a writable directory")
    if target.exists() and not os.access(target, os.W_OK):
        raise InputError(f"{option} {path}: file not writable")
