"""dsg-hil vcan's VM plan and output handling (the VM itself runs in CI through 'dsg-hil vcan')."""

from __future__ import annotations

import shutil

import pytest

from dsg_hil import vcan


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
