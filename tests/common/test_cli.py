"""run_main, the one main of dsg-hil, ecu-stub and python -m ecu_stub.identify: a status, or one 'error:' line and
the status of the error's branch; Ctrl-C 130, SIGTERM 143 (raised, or a stop event the command polls)."""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from dsg_hil.common.cli import Terminated, run_main
from dsg_hil.common.errors import InputError, ResultError, RunError


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="prog")
    parser.add_argument("--debug", action="store_true")
    return parser.parse_args(argv)


def raising(exc: BaseException):
    def run(args: argparse.Namespace) -> int:
        raise exc
    return run


@pytest.mark.parametrize("run, status, line", [
    (lambda args: None, 0, None),
    (lambda args: 5, 5, None),
    (raising(InputError("--x 3: must be even")), 2, "error: --x 3: must be even"),
    (raising(RunError("peer lost")), 1, "error: peer lost"),
    (raising(ResultError("out of band")), 3, "error: out of band"),
    (raising(ZeroDivisionError("a bug")), 1, "error: a bug"),
    (raising(KeyError()), 1, "error: KeyError"),  # an error without a message is named by its type
    (raising(KeyboardInterrupt()), 130, "error: interrupted"),
    (raising(Terminated()), 143, "error: terminated"),
])
def test_status_and_one_error_line(capsys, run, status, line):
    assert run_main(parse, [], run) == status
    assert capsys.readouterr().err.splitlines() == ([line] if line else [])


def test_debug_shows_the_traceback():
    with pytest.raises(InputError, match="bad"):
        run_main(parse, ["--debug"], raising(InputError("bad")))


def test_usage_errors_are_argparse_s():
    with pytest.raises(SystemExit) as exc:
        run_main(parse, ["--nosuch"], lambda args: 0)
    assert exc.value.code == 2


def test_sigterm_raises_terminated_in_the_main_thread_and_the_handler_is_restored(capsys):
    before = signal.getsignal(signal.SIGTERM)

    def run(args: argparse.Namespace) -> int:
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # the handler raises Terminated out of a sleep
            time.sleep(0.01)
        return 0  # not reached

    assert run_main(parse, [], run) == 143
    assert capsys.readouterr().err.splitlines() == ["error: terminated"]
    assert signal.getsignal(signal.SIGTERM) is before


def test_sigterm_sets_the_stop_event_of_a_command_that_ends_itself(capsys):
    stop = threading.Event()

    def run(args: argparse.Namespace) -> int:
        os.kill(os.getpid(), signal.SIGTERM)
        assert stop.wait(10)  # the command sees it and ends cleanly
        print("counts: 0 frames", file=sys.stderr)
        return 0

    assert run_main(parse, [], run, stop) == 143
    assert capsys.readouterr().err.splitlines() == ["counts: 0 frames"]


def test_importing_it_loads_the_standard_library_only():
    """ecu-stub and every --help start with it: no numpy, cantools, python-can (nor the rest of dsg_hil)."""
    code = ("import sys; import dsg_hil.common.cli; "
            "print(' '.join(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('numpy', 'cantools', 'can', 'scipy') or m.startswith('dsg_hil.') and not m.startswith("
            "'dsg_hil.common'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == []


def test_a_signal_held_acts_when_the_block_ends_and_an_ignored_sigint_stays_ignored():
    from dsg_hil.common.cli import signals_held

    reached = []
    # Python's Ctrl-C handler, as in a terminal (a suite started in the background has SIGINT ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            with signals_held():
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(100):
                    time.sleep(0.001)  # the handler has run by now, and held it
                reached.append(True)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert reached == [True]
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with signals_held():
            os.kill(os.getpid(), signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.parametrize(("preset", "numpy_first", "expected"), [(None, False, "1"), ("4", False, "4"),
                                                                 (None, True, None)])
def test_one_blas_thread_unless_the_user_set_theirs_or_numpy_is_loaded(preset, numpy_first, expected):
    """one_blas_thread (run_main calls it first): OPENBLAS_NUM_THREADS=1 in a fresh process, a user's value kept, and
    nothing once numpy is imported (too late to take effect)."""
    code = ("import os, sys\n" + ("import numpy\n" if numpy_first else "") +
            "from dsg_hil.common.cli import one_blas_thread\none_blas_thread()\n"
            "print(os.environ.get('OPENBLAS_NUM_THREADS'))")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if preset is not None:
        env["OPENBLAS_NUM_THREADS"] = preset
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    assert out.strip() == str(expected)
