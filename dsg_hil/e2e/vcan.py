"""Run a command where a real SocketCAN ``vcan0`` exists: natively (already there, or created with
``modprobe vcan`` + ``ip link``), or else inside a throw-away VM with a stock kernel (virtme-ng + QEMU software
emulation), with the results written back to the host.

Many kernels have no CAN at all (containers, cloud kernels, CI runners). The VM sees the host's filesystem
read-only, so the same venv and checkout run inside it; ``outdir`` is the one writable directory shared back.
The directories Python reads there come through a second, cached view of the host (see :func:`cached_dirs`).
"""

from __future__ import annotations

import collections
import contextlib
import os
import re
import shlex
import signal
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..common.errors import InputError, RunError

__all__ = ["BOOTED", "BOOT_TAIL", "CACHED_TAG", "CONSOLE", "ENV_DURATION", "ENV_OUTDIR", "ENV_REQUIRE", "ENV_WHERE",
           "RUN_SCRIPT", "SYSTEM_PACKAGES", "VCAN", "VcanError", "VmPlan", "cached_dirs", "compiled_code_env",
           "create_vcan", "find_kernel", "install_system_packages", "missing_system_packages", "output_tail",
           "run_in_vm", "vcan_present", "vm_plan", "warm_compiled_code", "with_load"]

VCAN = "vcan0"
BOOTED = "booted"  # written in outdir by the VM as it starts the command (the boot watchdog's sign)
CONSOLE = "console.txt"  # the VM's whole console (kernel messages included), in outdir
RUN_SCRIPT = "vm-run.sh"  # what the VM runs, in outdir
BOOT_TAIL = 15  # console lines shown for a boot that hung
CACHED_TAG = "dsg_hil_host"  # the 9p tag of the host's root exported a second time, for the cached view
CACHED_VIEW = "/run/dsg-hil-host"  # where the VM mounts it
ENV_REQUIRE = "DSG_HIL_REQUIRE_VCAN"  # tests that need vcan fail (instead of skipping) when it is set
ENV_DURATION = "DSG_HIL_VCAN_DURATION"  # simulated seconds of the end-to-end scenarios
ENV_OUTDIR = "DSG_HIL_VCAN_OUTDIR"  # where the end-to-end tests leave their logs
ENV_WHERE = "DSG_HIL_VCAN_WHERE"  # "native" or "emulated VM (QEMU TCG)": where the figures come from


class VcanError(RunError):
    """Neither a native vcan0 nor the VM can be had, or the VM failed; the message says what to install."""


# What the end-to-end tests need of the system, by the command (or file) that shows it is there: Debian's package.
SYSTEM_PACKAGES: dict[str, str] = {
    "candump": "can-utils",             # candump -L records, canplayer replays, cangen floods (every run)
    "stress-ng": "stress-ng",           # --load N
    "qemu-system-x86_64": "qemu-system-x86",  # the VM: QEMU's software emulation
    "busybox": "busybox-static",        # virtme-ng builds the VM's initramfs with it
    "/boot/vmlinuz-*": "linux-image-amd64",   # a stock kernel that ships vcan.ko
}


def missing_system_packages(*, vm: bool, load: bool, kernel: bool = True) -> list[str]:
    """The Debian packages of :data:`SYSTEM_PACKAGES` this run needs and the machine lacks (QEMU and busybox only
    for a VM, a kernel only for a VM without ``--kernel``, stress-ng only with ``load``)."""
    wanted = ["candump"] + (["stress-ng"] if load else []) + (["qemu-system-x86_64", "busybox"] if vm else []) + (
        ["/boot/vmlinuz-*"] if vm and kernel else [])
    missing = []
    for need in wanted:
        there = any(Path("/boot").glob("vmlinuz-*")) if need.startswith("/") else shutil.which(need) is not None
        if not there:
            missing.append(SYSTEM_PACKAGES[need])
    return missing


def install_system_packages(packages: list[str], say: Callable[[str], object] = print) -> None:
    """``apt-get install`` ``packages``, as root or through password-less ``sudo``, saying what it installs;
    :class:`VcanError` with the command to run by hand where neither is possible or the install fails."""
    if not packages:
        return
    by_hand = f"apt-get install {' '.join(packages)}"
    if shutil.which("apt-get") is None:
        raise VcanError(f"missing {', '.join(packages)} and no apt-get here: install them by hand")
    prefix: list[str] = []
    if os.geteuid() != 0:
        if shutil.which("sudo") is None or subprocess.run(["sudo", "-n", "true"], capture_output=True).returncode:
            raise VcanError(f"--install needs root or password-less sudo: run 'sudo {by_hand}'")
        prefix = ["sudo", "-n"]
    say(f"installing system packages: {' '.join(packages)} (apt-get, {'sudo' if prefix else 'as root'})")
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    for cmd in (["apt-get", "update", "-qq"], ["apt-get", "install", "-y", "-qq", *packages]):
        done = subprocess.run(prefix + cmd, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            raise VcanError(f"'{' '.join(cmd)}' failed (exit {done.returncode}): "
                            f"{(done.stderr or done.stdout).strip()[-300:]}")


def vcan_present() -> bool:
    return Path("/sys/class/net", VCAN).exists()


def create_vcan() -> str | None:
    """Try ``modprobe vcan``, ``ip link add`` and the CAN FD MTU; returns None on success, else why it failed."""
    steps = (["modprobe", "vcan"], ["ip", "link", "add", "dev", VCAN, "type", "vcan"],
             ["ip", "link", "set", VCAN, "mtu", "72"], ["ip", "link", "set", "up", VCAN])  # mtu 72: CAN FD frames
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
    ends, whose exit status is kept. A hog that is gone after a second, or that ended by itself before the command
    did (its status neither 0 nor that of our SIGTERM), fails the run (exit 1): it was not run under load."""
    hog = _tool("stress-ng", "apt-get install stress-ng (for --load)")
    script = (f'{shlex.quote(hog)} --cpu {int(workers)} --temp-path /tmp --quiet & hog=$!; sleep 1; '
              'kill -0 $hog 2>/dev/null || { echo "error: stress-ng did not start" >&2; exit 1; }; "$@"; rc=$?; '
              'kill $hog 2>/dev/null; wait $hog; hrc=$?; case $hrc in 0|143) ;; *) echo "error: stress-ng ended by '
              'itself (exit $hrc): the run was not under load" >&2; [ $rc -ne 0 ] || rc=1;; esac; exit $rc')
    return ["sh", "-c", script, "sh", *command]


@dataclass(frozen=True)
class VmPlan:
    """``argv`` boots the VM, which runs ``script`` (written to ``outdir/vm-run.sh`` as the VM is booted)."""

    argv: list[str]
    outdir: Path
    script: str = ""


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


def cached_dirs(cwd: Path, env: dict[str, str]) -> list[str]:
    """The host directories the VM's Python reads, to be seen through a cached view: the interpreter's base prefix
    (the standard library), the venv, the working directory and ``PYTHONPATH``'s entries; existing ones, parents
    before children, none that holds another, never ``/`` nor one under ``/tmp`` (the VM's writable overlay),
    ``/run``, ``/proc``, ``/sys`` or ``/dev``.

    vng mounts the host's root with 9p's default ``cache=none``: every stat, open and read of every module of every
    process goes to the host, through QEMU's main loop. Measured in the VM (QEMU TCG, 2-core host, idle): a
    0.1-s ``dsg-hil run`` took 34 s (user 15 s, sys 5.5 s) uncached, 21-22 s (user 12.5 s, sys 4.7 s) through a
    ``cache=loose`` view once warm; ``import numpy`` 6.4-7.4 s against 3.1-3.5 s; the vcan suite beside 2 CPU hogs
    2,553 s against 584 s (17 passed both, each alone on the machine). Nothing on the host changes these
    directories while the VM runs, which is what ``cache=loose`` assumes (no coherence with the host)."""
    candidates = [sys.base_prefix, sys.prefix, str(cwd), *env.get("PYTHONPATH", "").split(os.pathsep)]
    dirs: list[str] = []
    for raw in candidates:
        if not raw:
            continue
        path = Path(raw).resolve()
        if not path.is_dir() or path == Path("/") or path.parts[1] in ("tmp", "run", "proc", "sys", "dev"):
            continue
        dirs.append(str(path))
    kept: list[str] = []
    for name in sorted(set(dirs)):  # a parent sorts before its children
        if not any(Path(name).is_relative_to(parent) for parent in kept):
            kept.append(name)
    return kept


def _cached_view_script(dirs: list[str], outdir: Path) -> str:
    """Mount the second export (:data:`CACHED_TAG`) read-only with ``cache=loose`` and bind ``dirs`` from it over
    their uncached selves; ``outdir`` (vng's writable mount) is bound back on top where it lies inside one. A
    failure leaves the VM reading uncached, as before, and says so."""
    out, stash, view = shlex.quote(str(outdir)), "/run/dsg-hil-out", CACHED_VIEW
    binds = " && ".join(f"mount --bind {view}{shlex.quote(d)} {shlex.quote(d)}" for d in dirs) or "true"
    return (f"( mkdir -p {view} {stash} && mount -t 9p -o ro,trans=virtio,version=9p2000.L,access=any,"
            f"msize=524288,cache=loose {CACHED_TAG} {view} && mount --bind {out} {stash} && {binds} && "
            f"mount --bind {stash} {out} ) || echo 'the cached view of the host failed: reading it uncached'")


def vm_plan(command: list[str], outdir: Path, kernel: Path, env: dict[str, str], cwd: Path,
            memory: str = "2G", cpus: int = 2) -> VmPlan:
    """The vng invocation that boots ``kernel``, brings up vcan0 and runs ``command`` in ``cwd``."""
    vng = _tool("vng", "pip install virtme-ng (and apt-get install qemu-system-x86 busybox-static)")
    _tool("busybox", "apt-get install busybox-static (vng builds its initramfs with it)")
    _tool("qemu-system-x86_64", "apt-get install qemu-system-x86")
    exports = {"PATH": f"{Path(sys.executable).parent}:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin",
               "HOME": "/tmp", "MPLCONFIGDIR": "/tmp/mpl", "PYTHONDONTWRITEBYTECODE": "1",
               "PYTHONUNBUFFERED": "1", **env}  # unbuffered: the console shows each test as it ends
    script = "; ".join([
        f"date +%s > {shlex.quote(str(outdir / BOOTED))}",
        "modprobe vcan && ip link add dev vcan0 type vcan && ip link set vcan0 mtu 72 && ip link set up vcan0"
        " || echo 'vcan setup failed'",  # (mtu 72: CAN FD frames)
        _cached_view_script(cached_dirs(cwd, env), outdir),
        *(f"export {k}={shlex.quote(v)}" for k, v in exports.items()),
        f"cd {shlex.quote(str(cwd))}",
        f"( {' '.join(shlex.quote(c) for c in command)}; echo $? > {shlex.quote(str(outdir / 'rc'))} ) 2>&1"
        f" | tee {shlex.quote(str(outdir / 'output.txt'))}",
    ])
    # The host's root once more under CACHED_TAG, for the cached view (vng's own root mount is 9p's cache=none).
    export = (f"-fsdev local,id={CACHED_TAG},path=/,security_model=none,readonly=on,multidevs=remap "
              f"-device virtio-9p-pci,fsdev={CACHED_TAG},mount_tag={CACHED_TAG}")
    # The script goes in a file: vng passes --exec on the kernel's command line, whose 2048 bytes (x86) a long
    # command overflows, and this kernel then panics in its first second (a fortify check on the command line,
    # 'kernel BUG at lib/string_helpers.c') with QEMU idle for good: the hangs of the suite under --load.
    argv = [vng, "--disable-kvm", "--verbose", "--rwdir", str(outdir), "--run", str(kernel), "--memory", memory,
            "--cpus", str(cpus), f"--qemu-opts={export}", "--exec", f"sh {shlex.quote(str(outdir / RUN_SCRIPT))}"]
    return VmPlan(argv, outdir, script + "\n")


def run_in_vm(plan: VmPlan, timeout: float, boot_timeout: float = 300.0, attempts: int = 3,
              say: Callable[[str], object] = print) -> int:
    """Boot, run, and return the command's exit status (read back from the shared directory).

    A VM that has not started the command within ``boot_timeout`` seconds is killed and booted again, up to
    ``attempts`` boots in all (under QEMU's software emulation a boot takes 30 s to a few minutes; a kernel that
    panics early leaves the emulator idle for good, as an overlong kernel command line did, see :func:`vm_plan`).
    ``timeout`` bounds the whole, boots included. The VM's console is relayed line by line through a pipe (never
    handed our stdout, which QEMU could reopen and write from offset 0 when it is a file), without its terminal
    control characters."""
    rc_file, booted = plan.outdir / "rc", plan.outdir / BOOTED
    deadline = time.monotonic() + timeout
    if plan.script:
        (plan.outdir / RUN_SCRIPT).write_text(plan.script, encoding="utf-8")
    for attempt in range(1, attempts + 1):
        rc_file.unlink(missing_ok=True)
        booted.unlink(missing_ok=True)
        outcome, boot_lines = _boot_once(plan, deadline, boot_timeout, booted, say)
        if outcome != "no boot":
            break
        say(f"the VM did not start the command within {boot_timeout:g} s (boot {attempt} of {attempts}); its "
            f"console's last lines ({plan.outdir / CONSOLE}):\n  " + "\n  ".join(boot_lines or ["(nothing)"]))
        if attempt < attempts:
            say("killed it, booting again")
    else:
        raise VcanError(f"the VM did not start the command within {boot_timeout:g} s in {attempts} boots")
    if outcome == "timeout" and not rc_file.exists():
        raise VcanError(f"the VM did not finish within {timeout:g} s")
    if not rc_file.exists():
        raise VcanError("the VM ended without the command's exit status (see its output above)")
    return int(rc_file.read_text().strip() or 1)


def _boot_once(plan: VmPlan, deadline: float, boot_timeout: float, booted: Path,
               say: Callable[[str], object]) -> tuple[str, list[str]]:
    """One boot: "ended" (the VM stopped by itself), "no boot" (killed: the command had not started within
    ``boot_timeout``) or "timeout" (killed at ``deadline``), and the console's last lines before the command
    started. The whole console goes to ``outdir/console.txt``, our output gets it from the command's start. The VM
    runs in a session of its own, so that killing it kills QEMU and every helper vng started."""
    env = {**os.environ, "PATH": f"{Path(plan.argv[0]).parent}:{os.environ.get('PATH', '')}"}
    started = time.monotonic()
    proc = subprocess.Popen(plan.argv, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, start_new_session=True)
    outcome, seen = ["ended"], [False]
    done = threading.Event()

    def saw_boot() -> bool:
        if not seen[0] and booted.exists():
            seen[0] = True
            say(f"the VM booted and started the command in {time.monotonic() - started:.0f} s")
        return seen[0]

    def watch() -> None:
        while not done.wait(1.0):
            now = time.monotonic()
            up = saw_boot()
            why = "timeout" if now >= deadline else "no boot" if not up and now - started > boot_timeout else ""
            if why:
                outcome[0] = why
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                return

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    assert proc.stdout is not None  # stdout=PIPE
    boot_lines: collections.deque[str] = collections.deque(maxlen=BOOT_TAIL)
    try:
        with open(plan.outdir / CONSOLE, "a", encoding="utf-8", buffering=1) as console:  # line by line
            console.write(f"--- boot at {time.strftime('%H:%M:%S')} ---\n")
            for raw in proc.stdout:
                line = _printable(raw.decode(errors="replace"))
                if not line:
                    continue
                console.write(line + "\n")
                if seen[0] or saw_boot():  # the kernel's boot messages go to the file only
                    print(line, flush=True)
                else:
                    boot_lines.append(line)
        proc.wait()
    finally:
        done.set()
        watcher.join()
        saw_boot()
        if proc.poll() is None:  # we are leaving on an exception: take the VM down with us
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return outcome[0], list(boot_lines)


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
