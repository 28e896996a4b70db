"""Input and output files: read one with an error that names it, check an output path before a run."""

from __future__ import annotations

import os
from pathlib import Path

from .errors import InputError

__all__ = ["check_output_path", "read_input_file"]


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
