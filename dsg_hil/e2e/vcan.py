"""Run a command where a real SocketCAN ``vcan0`` exists: natively (already there, or created with
``modprobe vcan`` + ``ip link``), or else inside a throw-away VM with a stock kernel (virtme-ng + QEMU software
emulation), with the results written back to the host.

Many kernels have no CAN at all (containers, cloud kernels, CI runners). The VM sees the host's filesystem
read-only, so the same venv and checkout run inside it; ``outdir`` is the one writable directory shared back.
"""

from __future__ import annotations

import os
import re
import shlex
import signal
import shutil
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

from ..common.errors import InputError, RunError

__all__ = ["ENV_DURATION", "ENV_OUTDIR", "ENV_REQUIRE", "ENV_WHERE", "VCAN", "VcanError", "VmPlan",
           "compiled_code_env", "create_vcan", "find_kernel", "output_tail", "run_in_vm", "vcan_present",
           "vm_plan", "warm_compiled_code", "with_load"]

VCAN = "vcan0"
ENV_REQUIRE = "DSG_HIL_REQUIRE_VCAN"  # tests that need vcan fail (instead of skipping) when it is set
ENV_DURATION = "DSG_HIL_VCAN_DURATION"  # simulated seconds of the end-to-end scenarios
ENV_OUTDIR = "DSG_HIL_VCAN_OUTDIR"  # where the end-to-end tests leave their logs
ENV_WHERE = "DSG_HIL_VCAN_WHERE"  # "native" or "emulated VM (QEMU TCG)": where the figures come from


class VcanError(RunError):
    """Neither a native vcan0 nor the VM can be had, or the VM failed; the message says what to install."""


def vcan_present() -> bool:
    return Path("/sys/class/net", VCAN).exists()


def create_vcan() -> str | None:
    """Try ``modprobe vcan`` and ``ip link add``; returns None on success, else why it failed."""
    steps = (["modprobe", "vcan"], ["ip", "link", "add", "dev", VCAN, "type", "vcan"],
             ["ip", "link", "set", "up", VCAN])
    for cmd in steps:
        if shutil.which(cmd[0]) is None:
            return f"{cmd[0]} not found"
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0 and not vcan_present():
            return f"'{' '.join(cmd)}' failed: {(proc.stderr or proc.stdout).strip()}"
    return None if vcan_present() else "vcan0 did not appear"


def find_kernel(explicit: str | None = None) -> Path:
    """The VM's kernel image: ``explicit`` (``--kernel``; :class:`InputError` if it is no file), else the newest
    ``/boot/vmlinuz-*`` (:class:`VcanError` if there is none)."""
    if explicit:
        path = Path(explicit)
        if not path.is_file():
            raise InputError(f"--kernel {explicit}: no such file")
        return path
    images = sorted(Path("/boot").glob("vmlinuz-*"), key=lambda p: [int(x) if x.isdigit() else x
                                                                      for x in p.name.replace("-", ".").split(".")])
    if not images:
        raise VcanError("no kernel image in /boot for the VM: apt-get install linux-image-amd64 "
                        "(it ships vcan.ko), or pass --kernel")
    return images[-1]


def _tool(name: str, hint: str) -> str:
    found = shutil.which(name) or (str(Path(sys.executable).parent / name)
                                   if (Path(sys.executable).parent / name).exists() else None)
    if not found:
        raise VcanError(f"{name} not found: {hint}")
    return found


def with_load(command: list[str], workers: int) -> list[str]:
    """``command`` run beside ``stress-ng --cpu workers`` (a busy machine), where it runs (natively or in the VM);
    the hog (its scratch files in /tmp: the VM's working directory is read-only) is stopped when the command
    ends, whose exit status is kept."""
    hog = _tool("stress-ng", "apt-get install stress-ng (for --load)")
    script = (f'{shlex.quote(hog)} --cpu {int(workers)} --temp-path /tmp --quiet & hog=$!; sleep 1; '
              'kill -0 $hog 2>/dev/null || { echo "error: stress-ng did not start" >&2; exit 1; }; "$@"; rc=$?; '
              'kill $hog 2>/dev/null; wait $hog 2>/dev/null; exit $rc')
    return ["sh", "-c", script, "sh", *command]


@dataclass(frozen=True)
class VmPlan:
    argv: list[str]
    outdir: Path


def compiled_code_env(outdir: Path) -> dict[str, str]:
    """Where the VM finds the plant's compiled physics: numba's cache in the shared (writable) ``outdir``, built
    for a generic x86-64 CPU. The VM sees the rest of the host read-only, where numba would compile afresh in
    every process (minutes each under emulation), and its emulated CPU is not the host's (a cache made for the
    host's CPU is not used there)."""
    return {"NUMBA_CACHE_DIR": str(outdir / "numba-cache"), "NUMBA_CPU_NAME": "generic"}


def warm_compiled_code(env: dict[str, str]) -> None:
    """Compile the plant's physics on the host into the cache of :func:`compiled_code_env` (a 0.1-s closed loop
    on python-can's virtual bus), so the processes in the VM only load it."""
    done = subprocess.run([sys.executable, "-m", "dsg_hil", "run", "--interface", "virtual", "--channel",
                           "dsg_hil_warm", "--duration", "0.1"], env={**os.environ, **env}, capture_output=True,
                          text=True)
    if done.returncode != 0:
        raise VcanError(f"compiling the plant on the host failed: {done.stderr.strip()[-500:]}")


def vm_plan(command: list[str], outdir: Path, kernel: Path, env: dict[str, str], cwd: Path,
            memory: str = "2G", cpus: int = 2) -> VmPlan:
    """The vng invocation that boots ``kernel``, brings up vcan0 and runs ``command`` in ``cwd``."""
    vng = _tool("vng", "pip install virtme-ng (and apt-get install qemu-system-x86 busybox-static)")
    _tool("busybox", "apt-get install busybox-static (vng builds its initramfs with it)")
    _tool("qemu-system-x86_64", "apt-get install qemu-system-x86")
    exports = {"PATH": f"{Path(sys.executable).parent}:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin",
               "HOME": "/tmp", "MPLCONFIGDIR": "/tmp/mpl", "PYTHONDONTWRITEBYTECODE": "1", **env}
    script = "; ".join([
        "modprobe vcan && ip link add dev vcan0 type vcan && ip link set up vcan0 || echo 'vcan setup failed'",
        *(f"export {k}={shlex.quote(v)}" for k, v in exports.items()),
        f"cd {shlex.quote(str(cwd))}",
        f"( {' '.join(shlex.quote(c) for c in command)}; echo $? > {shlex.quote(str(outdir / 'rc'))} ) 2>&1"
        f" | tee {shlex.quote(str(outdir / 'output.txt'))}",
    ])
    argv = [vng, "--disable-kvm", "--rwdir", str(outdir), "--run", str(kernel), "--memory", memory,
            "--cpus", str(cpus), "--exec", script]
    return VmPlan(argv, outdir)


def run_in_vm(plan: VmPlan, timeout: float) -> int:
    """Boot, run, and return the command's exit status (read back from the shared directory).

    The VM's console is relayed line by line through a pipe (never handed our stdout, which QEMU could reopen
    and write from offset 0 when it is a file), without its terminal control characters."""
    rc_file = plan.outdir / "rc"
    rc_file.unlink(missing_ok=True)
    env = {**os.environ, "PATH": f"{Path(plan.argv[0]).parent}:{os.environ.get('PATH', '')}"}
    proc = subprocess.Popen(plan.argv, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT)
    timer = threading.Timer(timeout, proc.kill)
    timer.start()
    assert proc.stdout is not None  # stdout=PIPE
    try:
        for raw in proc.stdout:
            line = _printable(raw.decode(errors="replace"))
            if line:
                print(line, flush=True)
        proc.wait()
    finally:
        timer.cancel()
    if proc.returncode == -signal.SIGKILL and not rc_file.exists():
        raise VcanError(f"the VM did not finish within {timeout:g} s")
    if not rc_file.exists():
        raise VcanError("the VM ended without the command's exit status (see its output above)")
    return int(rc_file.read_text().strip() or 1)


def _printable(text: str) -> str:
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", text)  # ANSI control sequences of the console
    return "".join(ch for ch in text if ch.isprintable() or ch == "\t").rstrip()


def output_tail(outdir: Path, lines: int = 12) -> str:
    """The end of the command's output inside the VM, without the console's control characters."""
    path = outdir / "output.txt"
    if not path.exists():
        return ""
    clean = [_printable(line) for line in path.read_text(errors="replace").splitlines()]
    return "\n".join([line for line in clean if line][-lines:])
