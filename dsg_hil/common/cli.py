"""What every command line of dsg-hil and ecu-stub shares (standard library only: ``--help`` starts at once)."""

from __future__ import annotations

__all__ = ["Terminated", "raise_terminated"]


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that the run ends like on Ctrl-C: summary and log written."""


def raise_terminated(signum: int, frame: object) -> None:
    raise Terminated
