"""The one ``main`` of every command line: ``dsg-hil``, ``ecu-stub`` and ``python -m ecu_stub.identify``.

Standard library only, so ecu-stub and every ``--help`` start without numpy or cantools. :func:`run_main` parses
the arguments (argparse ends a usage error itself: its usage and ``PROG: error: ...``, exit 2), runs the command
and turns how it ended into the exit status of :mod:`dsg_hil.common.errors` and at most one line on stderr:

* the command returned: its status (``None``: 0);
* it raised an error: ``error: <message>`` and the status of the error's branch (2 bad input, 1 run failed or an
  unexpected error, 3 out of band); ``--debug`` lets it through for the traceback;
* Ctrl-C: ``error: interrupted``, 130; SIGTERM: ``error: terminated``, 143 (:class:`Terminated` raised in the main
  thread), or, when the command polls a ``stop`` event, the event set and 143 once the command has ended itself.

So at any moment from the first line of ``main``: the handlers are installed before the arguments are parsed, and a
signal that comes while they are (the command's modules being imported) is held until they are, so the command
(``cut_short``, e.g. the summary of a run that never started) knows its options; a command holds signals as well
while it sets up (:func:`signals_held`: a KeyboardInterrupt inside an import or numba's compiler leaves a
traceback, a half-imported module or a wrong exit status behind). Before ``main`` runs (the interpreter starting,
a few standard-library imports) Python's own handling applies: an entry point imports nothing else before it.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from .errors import EXIT_OK, EXIT_SIGINT, EXIT_SIGTERM, exit_code

__all__ = ["Terminated", "one_blas_thread", "raise_terminated", "run_main", "signals_held"]


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that the run ends like on Ctrl-C: summary and log written."""


def raise_terminated(signum: int, frame: object) -> None:
    """The SIGTERM handler of :func:`run_main`: raise :class:`Terminated`."""
    raise Terminated


def _error(message: str, status: int) -> int:
    print(f"error: {message}", file=sys.stderr, flush=True)
    return status


def one_blas_thread() -> None:
    """One OpenBLAS thread for a command's process (``OPENBLAS_NUM_THREADS=1``, numpy's and scipy's), unless the user
    set theirs; only before numpy is imported, where it takes effect. The plant's matrices are 12 x 12, where BLAS
    threads only cost: woken by a run's set-up (its matrix exponentials) they spin for a while, 0.1-0.2 s of another
    core per run, and on a core shared by two hardware threads they slowed the lock-step loop by about 10 % (36-38
    against 40-42 us per period, bench/closed_loop_speed.py). Dask's workers have one already (its nanny)."""
    if "numpy" not in sys.modules:
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def run_main(parse: Callable[[list[str] | None], argparse.Namespace], argv: list[str] | None,
             run: Callable[[argparse.Namespace], int | None], stop: threading.Event | None = None,
             cut_short: Callable[[argparse.Namespace, str], None] | None = None) -> int:
    """Parse ``argv``, run the command, return its exit status (see the module). ``stop``: SIGTERM sets it
    instead of raising :class:`Terminated`, for a command that ends cleanly when asked (ecu-stub). ``cut_short(args,
    reason)``: called (further signals held) when Ctrl-C or SIGTERM ended the command, ``reason`` ``interrupted``
    or ``terminated``."""
    one_blas_thread()
    handler = raise_terminated if stop is None else lambda signum, frame: stop.set()
    main_thread = threading.current_thread() is threading.main_thread()  # only there can signals be handled
    previous = signal.getsignal(signal.SIGTERM) if main_thread else None
    args: argparse.Namespace | None = None
    try:
        # the options first (the command's modules imported): a signal acts once they are known. SIGTERM's handler
        # is set as the block ends, so no signal falls between the two (it would end the command unsummarised)
        with signals_held(then={signal.SIGTERM: handler}):
            args = parse(argv)
        status = int(run(args) or EXIT_OK)
    except (KeyboardInterrupt, Terminated) as exc:
        reason, status = ("interrupted", EXIT_SIGINT) if isinstance(exc, KeyboardInterrupt) else \
            ("terminated", EXIT_SIGTERM)
        with signals_held(act=False):  # a second Ctrl-C does not cut the summary short
            if cut_short is not None and args is not None:
                _call_cut_short(cut_short, args, reason)
            return _error(reason, status)
    except Exception as exc:  # noqa: BLE001 - the single exit point for errors of every command line
        if getattr(args, "debug", False):
            raise
        return _error(str(exc) or type(exc).__name__, exit_code(exc))
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return EXIT_SIGTERM if stop is not None and stop.is_set() else status


def _call_cut_short(cut_short: Callable[[argparse.Namespace, str], None], args: argparse.Namespace,
                    reason: str) -> None:
    """``cut_short`` of a command a signal ended; its own failure is one line, not a traceback."""
    try:
        cut_short(args, reason)
    except Exception as exc:  # noqa: BLE001 - the command is over: say what was not done, exit as signalled
        if getattr(args, "debug", False):
            raise
        print(f"error: {reason}: {exc or type(exc).__name__}", file=sys.stderr, flush=True)


@contextmanager
def signals_held(note: str | None = None, act: bool = True, then: dict[int, Any] | None = None) -> Iterator[None]:
    """SIGINT and SIGTERM held inside the block (noted, not acted on): for work a signal must not cut mid-way
    (imports, the plant's physics compiled, files and buses opened), and after which the command ends cleanly
    (a summary written). After it (``act``), the first one held is acted on by the handler it would have met
    (Ctrl-C: :exc:`KeyboardInterrupt`; ecu-stub's SIGTERM: its stop event set). ``note``: printed on stderr at the
    first one held, so a user whose Ctrl-C waits knows it was heard. ``then``: handlers to set after the block
    instead of those it found (and to act on a held signal with). An exception leaving the block wins over a
    held signal. A SIGINT the process ignores (started in the background) stays ignored; outside the main thread
    (where Python handles no signal) the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []

    def hold(signum: int, frame: object) -> None:
        if not held and note:
            print(note, file=sys.stderr, flush=True)
        held.append(signum)

    kinds = [sig for sig in (signal.SIGINT, signal.SIGTERM)  # not one ignored, nor one handled outside Python
             if signal.getsignal(sig) not in (signal.SIG_IGN, None)]
    handlers: dict[int, Any] = {sig: signal.signal(sig, hold) for sig in kinds}
    handlers.update(then or {})
    try:
        yield
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    if held and act:
        handler = handlers[held[0]]
        if callable(handler):
            handler(held[0], None)
        elif held[0] == signal.SIGINT:  # SIG_DFL: as the default action would, but cleanly
            raise KeyboardInterrupt
        else:
            raise Terminated
