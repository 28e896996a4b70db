"""dsg_hil.common.files: an output path that cannot be written fails before the run, in the user's words."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from dsg_hil.common.errors import InputError
from dsg_hil.common.files import check_output_path


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's virtual file system")
def test_a_virtual_file_system_is_named_as_one_not_as_a_missing_file() -> None:
    with pytest.raises(InputError) as info:
        check_output_path("--a2l", "/proc/x.a2l")
    assert str(info.value) == "--a2l /proc/x.a2l: /proc is not a writable directory (it takes no new files)"


def test_a_file_where_a_directory_is_needed_is_named(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("x")
    with pytest.raises(InputError, match=r"afile is not a writable directory$"):
        check_output_path("--log", str(tmp_path / "afile" / "run.log"))


def test_a_writable_place_passes_and_leaves_nothing_behind(tmp_path: Path) -> None:
    check_output_path("--log", str(tmp_path / "new" / "run.log"))
    assert list(tmp_path.iterdir()) == []
