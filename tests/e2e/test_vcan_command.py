"""dsg-hil vcan's VM plan and output handling (the VM itself runs in CI through 'dsg-hil vcan')."""

from __future__ import annotations

import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from dsg_hil.common.errors import InputError, RunError, exit_code
from dsg_hil.e2e import vcan


def test_vm_plan_brings_up_vcan_and_reports_the_status(tmp_path, monkeypatch):
    monkeypatch.setattr(vcan, "_tool", lambda name, hint: f"/usr/bin/{name}")
    plan = vcan.vm_plan(["python", "-m", "pytest", "-m", "vcan"], tmp_path, tmp_path / "vmlinuz",
                        {vcan.ENV_REQUIRE: "1"}, tmp_path)
    assert plan.argv[:2] == ["/usr/bin/vng", "--disable-kvm"] and "--rwdir" in plan.argv
    assert plan.argv[-2:] == ["--exec", f"sh {tmp_path / vcan.RUN_SCRIPT}"]
    script = plan.script
    assert script.startswith(f"date +%s > {tmp_path / vcan.BOOTED}; modprobe vcan && ip link add dev vcan0 type vcan"
                             " && ip link set vcan0 mtu 72 && ip link set up vcan0")
    assert f"export {vcan.ENV_REQUIRE}=1" in script
    assert f"echo $? > {tmp_path / 'rc'}" in script and "output.txt" in script


def test_the_vm_reads_python_s_directories_through_a_cached_view(tmp_path, monkeypatch):
    """vng's root is 9p without a cache (every stat and read of every import goes to the host): the plan exports
    the root once more and the VM binds the interpreter's, the venv's and the checkout's directories from a
    cache=loose mount of it, then its writable log directory back on top where it lay inside one of them."""
    monkeypatch.setattr(vcan, "_tool", lambda name, hint: f"/usr/bin/{name}")
    monkeypatch.setattr(vcan.sys, "base_prefix", "/usr")
    monkeypatch.setattr(vcan.sys, "prefix", "/work/ck/.venv")
    monkeypatch.setattr(vcan.Path, "is_dir", lambda self: str(self) != "/gone")
    outdir = Path("/work/ck/logs")
    env = {"PYTHONPATH": os.pathsep.join(["/work/ck/src", "/gone", "", "/tmp/co", "/", "/run/x", "/opt/lib"])}
    assert vcan.cached_dirs(Path("/work/ck"), env) == ["/opt/lib", "/usr", "/work/ck"]
    plan = vcan.vm_plan(["true"], outdir, tmp_path / "vmlinuz", env, Path("/work/ck"))
    export = next(a for a in plan.argv if a.startswith("--qemu-opts="))
    assert f"mount_tag={vcan.CACHED_TAG}" in export and "readonly=on" in export
    assert plan.argv.index(export) < plan.argv.index("--exec")
    steps = plan.script.split("; ")
    view = next(s for s in steps if "cache=loose" in s)
    assert steps.index(view) < next(i for i, s in enumerate(steps) if s.startswith("cd "))
    assert f"cache=loose {vcan.CACHED_TAG} " in view and "mount --bind /work/ck/logs /run/dsg-hil-out" in view
    assert "/run/dsg-hil-host/work/ck /work/ck" in view and "/run/dsg-hil-host/usr /usr" in view
    assert view.index("--bind /run/dsg-hil-host/work/ck ") < view.index("mount --bind /run/dsg-hil-out /work/ck/logs")
    assert "/tmp" not in view and "/gone" not in view and "/run/x" not in view and "reading it uncached" in view


def test_the_kernel_command_line_stays_short_whatever_the_command(tmp_path, monkeypatch):
    """vng passes --exec on the kernel's command line (2048 bytes on x86; a longer one panicked the VM's kernel at
    boot): the command, its environment and the load's wrapper go in the script file, never there."""
    monkeypatch.setattr(vcan, "_tool", lambda name, hint: f"/usr/bin/{name}")
    long = vcan.with_load(["python", "-m", "pytest", *["-k", "x" * 500] * 4], 4)
    plan = vcan.vm_plan(long, tmp_path, tmp_path / "vmlinuz", {"PYTHONPATH": "/a" * 500}, tmp_path)
    assert len(plan.argv[-1]) < 200 and len(plan.script) > 3000
    plan.argv[:] = ["true"]  # boot nothing: the script is written where the VM reads it
    with pytest.raises(vcan.VcanError, match="without the command's exit status"):
        vcan.run_in_vm(plan, timeout=60, say=lambda _: None)
    assert (tmp_path / vcan.RUN_SCRIPT).read_text() == plan.script


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
    """A hog that fails is caught whether it is gone by the check after a second or still starting then (a loaded
    machine: it ignores our SIGTERM so that it ends by itself, as a failing stress-ng does, whenever it runs)."""
    hog = tmp_path / "stress-ng"
    hog.write_text("#!/bin/sh\ntrap '' TERM\necho 'aborting' >&2\nexit 1\n")
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


def test_missing_system_packages_are_named_by_debian_package(monkeypatch):
    monkeypatch.setattr(shutil, "which", lambda name: None)
    monkeypatch.setattr(vcan.Path, "glob", lambda self, pattern: iter(()))
    assert vcan.missing_system_packages(vm=False, load=False) == ["can-utils"]
    assert vcan.missing_system_packages(vm=True, load=True) == [
        "can-utils", "stress-ng", "qemu-system-x86", "busybox-static", "linux-image-amd64"]
    assert "linux-image-amd64" not in vcan.missing_system_packages(vm=True, load=False, kernel=False)
    monkeypatch.setattr(shutil, "which", lambda name: f"/usr/bin/{name}")
    assert vcan.missing_system_packages(vm=False, load=True) == []


def test_install_without_root_or_sudo_names_the_command(monkeypatch):
    monkeypatch.setattr(vcan.os, "geteuid", lambda: 1000)
    monkeypatch.setattr(shutil, "which", lambda name: None if name == "sudo" else f"/usr/bin/{name}")
    with pytest.raises(vcan.VcanError, match=r"run 'sudo apt-get install can-utils stress-ng'"):
        vcan.install_system_packages(["can-utils", "stress-ng"])


def test_install_as_root_runs_apt_get_and_says_what(monkeypatch, tmp_path):
    apt = tmp_path / "apt-get"  # a stand-in that records its arguments (the real one would change this machine)
    apt.write_text(f"#!/bin/sh\necho \"$DEBIAN_FRONTEND $@\" >> {tmp_path / 'apt.args'}\n")
    apt.chmod(0o755)
    monkeypatch.setenv("PATH", f"{tmp_path}:{os.environ['PATH']}")
    monkeypatch.setattr(vcan.os, "geteuid", lambda: 0)
    said: list[str] = []
    vcan.install_system_packages(["can-utils"], say=said.append)
    assert said == ["installing system packages: can-utils (apt-get, as root)"]
    assert (tmp_path / "apt.args").read_text().splitlines() == [
        "noninteractive update -qq", "noninteractive install -y -qq can-utils"]
    apt.write_text("#!/bin/sh\necho 'E: Unable to locate package can-utils' >&2\nexit 100\n")
    with pytest.raises(vcan.VcanError, match="failed \\(exit 100\\): E: Unable to locate package can-utils"):
        vcan.install_system_packages(["can-utils"], say=said.append)
    vcan.install_system_packages([], say=said.append)  # nothing missing: nothing run, nothing said
    assert len(said) == 2


def _fake_vm(tmp_path, hangs: int):
    """A stand-in for vng (no VM, no vcan: this checks our supervision of the VM process only). Its first ``hangs``
    boots hang for good with a child process, as a stuck QEMU would; the next writes the boot sign, a line, and
    the command's status 7."""
    outdir = tmp_path / "out"
    outdir.mkdir()
    vng = tmp_path / "vng"
    vng.write_text(f"""#!/bin/sh
n=$(cat {tmp_path}/boots 2>/dev/null || echo 0); n=$((n + 1)); echo $n > {tmp_path}/boots
echo "[    0.0$n] booting, try $n"
if [ $n -le {hangs} ]; then sleep 300 & echo $! > {tmp_path}/child$n; wait; fi
date +%s > {outdir / vcan.BOOTED}; echo "\\033[1mtest passed\\033[0m"; echo 7 > {outdir / 'rc'}
""")
    vng.chmod(0o755)
    return vcan.VmPlan([str(vng)], outdir), outdir


def _alive(pid_file) -> bool:
    """The process runs (a killed one may stay a zombie a moment, until its new parent reaps it)."""
    for _ in range(50):
        try:
            state = Path(f"/proc/{int(pid_file.read_text())}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except FileNotFoundError:
            return False
        if state == "Z":
            return False
        time.sleep(0.1)
    return True


@pytest.mark.slow
def test_a_vm_that_hangs_at_boot_is_killed_and_booted_again(tmp_path, capsys):
    plan, _ = _fake_vm(tmp_path, hangs=1)
    said: list[str] = []
    assert vcan.run_in_vm(plan, timeout=120, boot_timeout=2, attempts=3, say=said.append) == 7
    assert (tmp_path / "boots").read_text().strip() == "2"
    assert not _alive(tmp_path / "child1")  # the hung boot's whole process group went with it
    out = capsys.readouterr().out
    assert "test passed" in out and "booting, try 1" not in out  # boot messages: in the console file only
    assert said[0].startswith("the VM did not start the command within 2 s (boot 1 of 3); its console's last lines")
    assert said[0].endswith("\n  [    0.01] booting, try 1") and said[1] == "killed it, booting again"
    assert said[2].startswith("the VM booted and started the command in")
    console = (plan.outdir / vcan.CONSOLE).read_text()
    assert "booting, try 1" in console and "booting, try 2" in console and "test passed" in console


@pytest.mark.slow
def test_a_vm_that_never_boots_fails_the_run_after_its_boots(tmp_path):
    plan, _ = _fake_vm(tmp_path, hangs=9)
    with pytest.raises(vcan.VcanError, match="did not start the command within 1 s in 2 boots") as exc:
        vcan.run_in_vm(plan, timeout=120, boot_timeout=1, attempts=2, say=lambda _: None)
    assert exit_code(exc.value) == 1 and (tmp_path / "boots").read_text().strip() == "2"
    assert not _alive(tmp_path / "child2")


@pytest.mark.slow
def test_the_time_limit_holds_after_the_boot(tmp_path):
    """Booted but never done: killed at ``timeout`` (boots included), not booted again."""
    plan, outdir = _fake_vm(tmp_path, hangs=0)
    vng = plan.argv[0]
    with open(vng, "a") as f:
        f.write("rm " + str(outdir / "rc") + "; sleep 300\n")
    with pytest.raises(vcan.VcanError, match="did not finish within 3 s"):
        vcan.run_in_vm(plan, timeout=3, boot_timeout=60, say=lambda _: None)
    assert (tmp_path / "boots").read_text().strip() == "1"
