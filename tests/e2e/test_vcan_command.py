"""dsg-hil vcan's VM plan and output handling (the VM itself runs in CI through 'dsg-hil vcan')."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from dsg_hil.common.errors import InputError, RunError, exit_code
from dsg_hil.e2e import vcan


def test_vm_plan_brings_up_vcan_and_reports_the_status(tmp_path, monkeypatch):
    monkeypatch.setattr(vcan, "_tool", lambda name, hint: f"/usr/bin/{name}")
    plan = vcan.vm_plan(["python", "-m", "pytest", "-m", "vcan"], tmp_path, tmp_path / "vmlinuz",
                        {vcan.ENV_REQUIRE: "1"}, tmp_path)
    assert plan.argv[:2] == ["/usr/bin/vng", "--disable-kvm"] and "--rwdir" in plan.argv
    script = plan.argv[-1]
    assert script.startswith("modprobe vcan && ip link add dev vcan0 type vcan && ip link set up vcan0")
    assert f"export {vcan.ENV_REQUIRE}=1" in script
    assert f"echo $? > {tmp_path / 'rc'}" in script and "output.txt" in script


def test_output_tail_drops_console_garbage(tmp_path):
    (tmp_path / "output.txt").write_text("a\n\x1b[2K   \n" + "".join(f"line {i}\r\n" for i in range(20)))
    tail = vcan.output_tail(tmp_path, lines=3)
    assert tail.splitlines() == ["line 17", "line 18", "line 19"]
    assert vcan._printable("\x1b[2K\x1b[1;32mPASSED\x1b[0m\r") == "PASSED"
    assert vcan.output_tail(tmp_path / "nothing") == ""


def test_missing_tools_are_named(monkeypatch, tmp_path):
    monkeypatch.setattr(shutil, "which", lambda name: None)
    monkeypatch.setattr(vcan.sys, "executable", str(tmp_path / "python"))
    with pytest.raises(vcan.VcanError, match="vng not found: pip install virtme-ng"):
        vcan.vm_plan(["true"], tmp_path, tmp_path / "k", {}, tmp_path)


def test_load_runs_the_command_beside_cpu_hogs_and_keeps_its_status(tmp_path, monkeypatch):
    hog = tmp_path / "stress-ng"  # a stand-in that records its arguments and runs until killed
    hog.write_text(f"#!/bin/sh\necho \"$@\" > {tmp_path / 'hog.args'}\nexec sleep 30\n")
    hog.chmod(0o755)
    monkeypatch.setattr(vcan, "_tool", lambda name, hint: str(hog))
    wrapped = vcan.with_load(["sh", "-c", "sleep 0.2; exit 3"], 4)
    assert subprocess.run(wrapped, timeout=20).returncode == 3
    assert (tmp_path / "hog.args").read_text().split() == ["--cpu", "4", "--temp-path", "/tmp", "--quiet"]


def test_missing_stress_ng_is_named(monkeypatch, tmp_path):
    monkeypatch.setattr(shutil, "which", lambda name: None)
    monkeypatch.setattr(vcan.sys, "executable", str(tmp_path / "python"))
    with pytest.raises(vcan.VcanError, match="stress-ng not found: apt-get install stress-ng"):
        vcan.with_load(["true"], 2)


def test_load_that_cannot_start_fails_the_run(tmp_path, monkeypatch):
    hog = tmp_path / "stress-ng"
    hog.write_text("#!/bin/sh\necho 'aborting' >&2\nexit 1\n")
    hog.chmod(0o755)
    monkeypatch.setattr(vcan, "_tool", lambda name, hint: str(hog))
    assert subprocess.run(vcan.with_load(["true"], 2), timeout=20).returncode == 1


def test_a_missing_kernel_is_bad_input_and_no_vm_a_failed_run(monkeypatch, tmp_path):
    """--kernel naming no file: exit 2 (InputError); no kernel in /boot at all: exit 1 (VcanError, a RunError)."""
    with pytest.raises(InputError, match=f"--kernel {tmp_path / 'nosuch'}: no such file"):
        vcan.find_kernel(str(tmp_path / "nosuch"))
    monkeypatch.setattr(vcan.Path, "glob", lambda self, pattern: iter(()))
    with pytest.raises(vcan.VcanError, match="no kernel image in /boot") as exc:
        vcan.find_kernel()
    assert isinstance(exc.value, RunError) and exit_code(exc.value) == 1
