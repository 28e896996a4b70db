"""Input and output files: read one with an error that names it, check an output path before a run."""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path

from .errors import InputError

__all__ = ["check_output_path", "read_input_file", "user_cache_dir"]


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
    cannot be written: a directory (a file) or a name ending in a path separator, or a place where nothing can be
    written. Missing parents are created when the file is written: the nearest existing one must take a new
    entry, which is tried (a temporary entry, removed at once: permission bits say nothing for root, nor on a
    read-only or virtual file system such as /proc)."""
    if path is None:
        return
    target = Path(path)
    if not directory and target.is_dir():
        raise InputError(f"{option} {path}: is a directory")
    if not directory and path.endswith(("/", os.sep)):
        raise InputError(f"{option} {path}: ends in a path separator: give a file name")
    if directory and target.exists():
        if not target.is_dir():
            raise InputError(f"{option} {path}: not a writable directory (a file)")
        _probe(option, path, target)
        return
    parent = target.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise InputError(f"{option} {path}: {parent} is not a writable directory")
    _probe(option, path, parent)
    if target.exists() and not os.access(target, os.W_OK):
        raise InputError(f"{option} {path}: file not writable")


def _probe(option: str, path: str, where: Path) -> None:
    """Whether ``where`` takes a new entry: a temporary directory made and removed."""
    try:
        tempfile.TemporaryDirectory(dir=where).cleanup()
    except OSError as exc:
        reason = _PROBE_REASONS.get(exc.errno or 0, exc.strerror or str(exc))
        raise InputError(f"{option} {path}: {where} is not a writable directory ({reason})") from None


# The probe's errors in a user's words: a virtual file system such as /proc answers "no such file" to a new entry.
_PROBE_REASONS = {
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.EROFS: "read-only file system",
    errno.ENOENT: "it takes no new files",
    errno.ENOSPC: "no space left",
    errno.EDQUOT: "disk quota exceeded",
}


def user_cache_dir(*parts: str) -> Path:
    """``dsg-hil/PARTS`` in the user's cache directory (``$XDG_CACHE_HOME``, by default ``~/.cache``)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base, "dsg-hil", *parts)
