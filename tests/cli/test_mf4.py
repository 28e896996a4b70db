"""ASAM MDF4 logs by extension (``--log run.mf4``) through python-can's MF4 writer and reader, which need asammdf
(the ``mf4`` extra); without it, one line naming the extra, before anything runs (issue 20, item 9)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from dsg_hil.cli import main
from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.logs import decoded_frames, log_codec

WITHOUT_ASAMMDF = ("import sys; sys.modules['asammdf'] = None; from dsg_hil.cli import main; "
                   "sys.exit(main(sys.argv[1:]))")  # as if the mf4 extra were not installed


def frames(path) -> list[tuple[float, str, dict]]:
    return [(round(t, 6), f.name, f.values) for t, f in decoded_frames(path, log_codec(load_dbc())) if f is not None]


def test_an_mf4_log_holds_the_frames_of_the_candump_log(tmp_path):
    pytest.importorskip("asammdf", reason="the mf4 extra is not installed")
    for name in ("run.log", "run.mf4"):
        assert main(["run", "-q", "--duration", "1", "--log", str(tmp_path / name)]) == 0
    mf4, candump = frames(tmp_path / "run.mf4"), frames(tmp_path / "run.log")
    assert len(mf4) > 500 and mf4 == candump


@pytest.mark.slow
def test_without_asammdf_an_mf4_log_is_one_error_naming_the_extra(tmp_path):
    proc = subprocess.run([sys.executable, "-c", WITHOUT_ASAMMDF, "run", "--duration", "1", "--log", "r.mf4",
                           "--summary", "s.json"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip() == "error: --log r.mf4: .mf4 (ASAM MDF4) logs need asammdf: pip install 'dsg-hil[mf4]'"
    assert list(tmp_path.iterdir()) == []  # nothing written, nothing ran
    (tmp_path / "old.mf4").write_bytes(b"MDF     4.10    ")
    proc = subprocess.run([sys.executable, "-c", WITHOUT_ASAMMDF, "report", "--from-log", "old.mf4", "--out", "rep"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stderr.strip().endswith("pip install 'dsg-hil[mf4]'"), proc.stderr
    assert not (tmp_path / "rep").exists()
