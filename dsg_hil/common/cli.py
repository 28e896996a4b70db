"""The one ``main`` of every command line: ``dsg-hil``, ``ecu-stub`` and ``python -m ecu_stub.identify``.

Standard library only, so ecu-stub and every ``--help`` start without numpy or cantools. :func:`run_main` parses
the arguments (argparse ends a usage error itself: its usage and ``PROG: error: ...``, exit 2), runs the command
and turns how it ended into the exit status of :mod:`dsg_hil.common.errors` and at most one line on stderr:

* the command returned: its status (``None``: 0);
* it raised an error: ``error: <message>`` and the status of the error's branch (2 bad input, 1 run failed or an
  unexpected error, 3 out of band); ``--debug`` lets it through for the traceback;
* Ctrl-C: ``error: interrupted``, 130; SIGTERM: ``error: terminated``, 143 (:class:`Terminated` raised in the main
  thread), or, when the command polls a ``stop`` event, the event set and 143 once the command has ended itself.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from collections.abc import Callable

from .errors import EXIT_OK, EXIT_SIGINT, EXIT_SIGTERM, exit_code

__all__ = ["Terminated", "raise_terminated", "run_main"]


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that the run ends like on Ctrl-C: summary and log written."""


def raise_terminated(signum: int, frame: object) -> None:
    """The SIGTERM handler of :func:`run_main`: raise :class:`Terminated`."""
    raise Terminated


def _error(message: str, status: int) -> int:
    print(f"error: {message}", file=sys.stderr, flush=True)
    return status


def run_main(parse: Callable[[list[str] | None], argparse.Namespace], argv: list[str] | None,
             run: Callable[[argparse.Namespace], int | None], stop: threading.Event | None = None) -> int:
    """Parse ``argv``, run the command, return its exit status (see the module). ``stop``: SIGTERM sets it
    instead of raising :class:`Terminated`, for a command that ends cleanly when asked (ecu-stub)."""
    args = parse(argv)
    handler = raise_terminated if stop is None else lambda signum, frame: stop.set()
    main_thread = threading.current_thread() is threading.main_thread()  # only there can signals be handled
    previous = signal.signal(signal.SIGTERM, handler) if main_thread else None
    try:
        status = int(run(args) or EXIT_OK)
    except KeyboardInterrupt:
        return _error("interrupted", EXIT_SIGINT)
    except Terminated:
        return _error("terminated", EXIT_SIGTERM)
    except Exception as exc:  # noqa: BLE001 - the single exit point for errors of every command line
        if getattr(args, "debug", False):
            raise
        return _error(str(exc) or type(exc).__name__, exit_code(exc))
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return EXIT_SIGTERM if stop is not None and stop.is_set() else status
