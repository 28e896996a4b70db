"""The package's exceptions and exit codes, one hierarchy (after python-can's CanError and cantools' Error).

In :mod:`dsg_hil.common`, the kernel ecu-stub may import, so that the plant and the TCU share them.

* :class:`InputError` (a ``ValueError``): a bad file, key, option or value; nothing ran. Exit 2.
* :class:`RunError` (a ``RuntimeError``): the run could not go on (peer lost, bus gone ...). Exit 1.
* :class:`ResultError`: the run finished but its result is outside its band. Exit 3.
"""

from __future__ import annotations

import signal

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
