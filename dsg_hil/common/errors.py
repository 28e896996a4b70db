"""Every error dsg-hil and ecu-stub raise on purpose, one tree (after python-can's ``can/exceptions.py``), and the
exit status of each branch. In :mod:`dsg_hil.common`, the kernel ecu-stub may import, so the plant and the TCU
share them; each class is defined where it belongs (the module in brackets) and derives from its branch here::

    Exception (Python standard library)
     +-- DsgHilError                                         exit 1
         +-- InputError (also a ValueError)                  exit 2: a bad file, key, option or value; nothing ran
         |   +-- ParameterError       (physics.params)       the plant's parameter file
         |   +-- ScenarioError        (sim.scenario)         a scenario file or a run's option
         |   +-- FaultError           (protocol.faults)      a [[fault]] table or --fault
         |   +-- ProtocolError        (protocol.codec)       the DBC: missing, unreadable, or lacks what is used
         |   |   +-- BindingError     (protocol.binding)     a binding file: unreadable, or not fitting its DBC
         |   +-- ProtectionError      (protocol.e2e)         a message's E2E protection: bad table or no fit
         |   +-- FrameError           (protocol.codec)       a received frame (dlc, crc, data_id, range, ...): rejected
         |   +-- LogError             (common.errors)        a recorded log: unreadable, not of the DBC, no data
         |   +-- CalibrationError     (ecu_stub.calibration) the TCU's calibration file
         |   +-- FmuError             (fmi.controller)       a controller FMU: unreadable, or a variable no DBC signal
         |   +-- FmuCallError         (fmi.slave)            an FMI host's call our FMUs refuse (logged, not raised)
         |   +-- SpaceError           (sweep.space)          a sweep's space file
         |   +-- LatentError          (sweep.latent)         a space's [latent] section (the space names its file)
         |   +-- DriverError          (sweep.drivers)        a sweep's driver setting that makes no behaviour
         |   +-- DiagError            (protocol.diag)        a UDS description (DIDs, DTCs) or the DBC's diagnostic IDs
         +-- RunError (also a RuntimeError)                  exit 1: the run could not go on
         |   +-- PeerTimeout          (common.errors)        no TCU answered the lock-step presence probe
         |   |   +-- PeerLost         (common.errors)        the TCU fell silent during a lock-step run
         |   +-- VcanError            (e2e.vcan)             neither a native vcan0 nor the VM can be had
         +-- ResultError                                     exit 3: the run finished, its result is out of band

    BaseException
     +-- KeyboardInterrupt (Ctrl-C)                          exit 130 (128 + SIGINT, as a shell reports it)
     +-- Terminated           (common.cli)                   exit 143: SIGTERM, raised in the main thread

Any other exception that ends a command is a bug: exit 1. :func:`dsg_hil.common.cli.run_main` prints the one
``error: ...`` line and returns the status.
"""

from __future__ import annotations

import signal

__all__ = ["EXIT_BAD_INPUT", "EXIT_OK", "EXIT_OUT_OF_BAND", "EXIT_RUN_FAILED", "EXIT_SIGINT", "EXIT_SIGTERM",
           "DsgHilError", "InputError", "LogError", "PeerLost", "PeerTimeout", "ResultError", "RunError", "exit_code"]

EXIT_OK, EXIT_RUN_FAILED, EXIT_BAD_INPUT, EXIT_OUT_OF_BAND = 0, 1, 2, 3
EXIT_SIGINT, EXIT_SIGTERM = 128 + signal.SIGINT, 128 + signal.SIGTERM  # as a shell reports a killed process


class DsgHilError(Exception):
    """Base of every error dsg-hil and ecu-stub raise on purpose; ``exit_code`` is its command's exit status."""

    exit_code = EXIT_RUN_FAILED


class InputError(DsgHilError, ValueError):
    """Bad input: the message names the file, key or option and what is wrong."""

    exit_code = EXIT_BAD_INPUT


class RunError(DsgHilError, RuntimeError):
    """The run failed (e.g. the peer was lost)."""

    exit_code = EXIT_RUN_FAILED


class ResultError(DsgHilError):
    """The run finished but its result is outside its band (``dsg-hil validate``, ``dsg-hil dbc``)."""

    exit_code = EXIT_OUT_OF_BAND


class LogError(InputError):
    """A recorded log that cannot be read, holds no frame of the DBC, or lacks the data asked of it (the message
    names the file)."""


class PeerTimeout(RunError):  # noqa: N818 - public name, kept
    """The TCU did not answer the lock-step presence probe in time."""


class PeerLost(PeerTimeout):
    """The TCU fell silent during a lock-step run (stop reason ``peer_lost``; the summary is valid so far)."""


def exit_code(exc: BaseException) -> int:
    """The exit status for an error that ends a command: its branch's, else 1 (an unexpected error)."""
    return exc.exit_code if isinstance(exc, DsgHilError) else EXIT_RUN_FAILED
