"""``dsg-hil vcan``: run the end-to-end tests (or any command) on a real SocketCAN vcan0, anywhere."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from ..common.build import EXPECT_ENV
from ..common.files import check_output_path
from ..e2e import vcan
from . import command_help
from .common import non_negative_int, positive_number, progress

__all__ = ["DEFAULT_TESTS", "add_subparser"]

# The end-to-end tests ship inside the package (dsg_hil/e2e), so this runs from a checkout and from a wheel alike.
DEFAULT_TESTS = ["python", "-m", "pytest", "-m", "vcan", "-p", "no:cacheprovider", "-v", "--durations=0",
                 "--pyargs", "dsg_hil.e2e"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "vcan", help=command_help("vcan"),
        description="Run COMMAND (default: the vcan end-to-end tests shipped with the package, 'pytest -m vcan "
                    "--pyargs dsg_hil.e2e') where a real SocketCAN vcan0 exists: natively if vcan0 is there or "
                    "can be created (modprobe vcan, ip link), else inside a throw-away VM with a stock kernel "
                    "(virtme-ng + QEMU software emulation; needs qemu-system-x86, busybox-static, "
                    "linux-image-amd64 and pip virtme-ng). The same command on a laptop with vcan and on a CI "
                    "runner without it. Exit status: COMMAND's (2 for a bad option, 1 when neither vcan0 nor the VM "
                    "can be had).")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--native", action="store_true", help="never use the VM")
    where.add_argument("--vm", action="store_true", help="always use the VM")
    parser.add_argument("--duration", type=positive_number, default=5.0, metavar="S",
                        help="simulated seconds of each end-to-end scenario (default 5; Python runs ~10x "
                             "slower under emulation)")
    parser.add_argument("--load", type=non_negative_int, default=0, metavar="N",
                        help="run COMMAND on a busy machine: beside 'stress-ng --cpu N' (N CPU hogs where the "
                             "command runs, in the VM or natively; needs stress-ng; default 0: idle)")
    parser.add_argument("--install", action="store_true",
                        help="install the system packages this run lacks (can-utils; stress-ng for --load; "
                             "qemu-system-x86, busybox-static, linux-image-amd64 for the VM) with apt-get, as root "
                             "or through password-less sudo, saying what it installs (default: name them and stop)")
    parser.add_argument("--kernel", metavar="FILE", help="kernel image for the VM (default: newest /boot/vmlinuz-*)")
    parser.add_argument("--outdir", metavar="DIR", help="writable directory for logs and results (default: a "
                        "temporary one, kept when the command fails)")
    parser.add_argument("--timeout", type=positive_number, default=4500.0, metavar="S",
                        help="VM time limit, boots included (default 4500: emulated on a 2-core machine, the suite "
                             "took 57 min for 12 of its 18 tests under --load 4)")
    parser.add_argument("--boot-timeout", type=positive_number, default=300.0, metavar="S",
                        help="a VM that has not started COMMAND within S seconds is killed and booted again, three "
                             "boots at most, its console's last lines shown (default 300; a boot takes 30 s to a few "
                             "minutes emulated)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="command to run (after --)")
    parser.set_defaults(func=_do_vcan)


def _do_vcan(args: argparse.Namespace) -> int:
    command = [c for c in args.command if c != "--"] or list(DEFAULT_TESTS)
    if command[0] == "python":
        command[0] = sys.executable
    kernel = vcan.find_kernel(args.kernel) if args.kernel else None  # bad input fails before anything is made
    check_output_path("--outdir", args.outdir, directory=True)
    native = False
    if not args.vm:
        if vcan.vcan_present():
            native = True
        else:
            reason = vcan.create_vcan()
            native = reason is None
            if not native:
                if args.native:
                    raise vcan.VcanError(f"no vcan0 and cannot create it: {reason}")
                progress(f"no vcan0 here ({reason}): running in a throw-away VM")
    missing = vcan.missing_system_packages(vm=not native, load=bool(args.load), kernel=kernel is None)
    if missing and args.install:
        vcan.install_system_packages(missing, say=progress)
    elif missing:
        raise vcan.VcanError(f"missing system packages: {' '.join(missing)} (apt-get install them, or run "
                             "'dsg-hil vcan --install' as root or with password-less sudo)")
    outdir = Path(args.outdir or tempfile.mkdtemp(prefix="dsg-hil-vcan-")).resolve()
    outdir.mkdir(parents=True, exist_ok=True)
    env = {vcan.ENV_REQUIRE: "1", vcan.ENV_DURATION: f"{args.duration:g}", vcan.ENV_OUTDIR: str(outdir)}
    for name in ("PYTHONPATH", EXPECT_ENV):  # the caller's, forwarded into the VM (e.g. a checkout other than the
        if os.environ.get(name):  # venv's; the compiled build required)
            env[name] = os.environ[name]
    # the tests run the installed package (the compiled build of a regular install) even where the working directory
    # is its checkout: 'python -m pytest' would put that first on sys.path
    env["PYTHONSAFEPATH"] = "1"
    if args.load:
        command = vcan.with_load(command, args.load)
    env[vcan.ENV_WHERE] = "native" if native else "emulated VM (QEMU TCG)"
    if native:
        progress(f"vcan0 present: running natively; logs in {outdir}")
        rc = subprocess.run(command, env={**os.environ, **env}).returncode
    else:
        kernel = kernel or vcan.find_kernel()
        env |= vcan.compiled_code_env(outdir)
        progress("compiling the plant's physics on the host for the VM (numba cache in the log directory)")
        vcan.warm_compiled_code(env)
        progress(f"booting {kernel.name} under QEMU (software emulation) with vcan0; logs in {outdir}")
        rc = vcan.run_in_vm(vcan.vm_plan(command, outdir, kernel, env, Path.cwd()), args.timeout,
                            boot_timeout=args.boot_timeout, say=progress)
        tail = vcan.output_tail(outdir)
        if tail:  # the console interleaves and garbles; repeat the end cleanly (full: output.txt)
            print(f"--- end of the command's output in the VM ({outdir / 'output.txt'}) ---\n{tail}", flush=True)
    load = f" beside {args.load} CPU hogs" if args.load else ""
    progress(f"{'native' if native else 'VM'} vcan run{load} finished with status {rc}; logs in {outdir}")
    return rc
