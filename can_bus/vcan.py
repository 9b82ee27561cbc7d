"""A real SocketCAN vcan0 on a machine whose kernel has no CAN support (DESIGN.md section 7).

Debian's user-mode-linux package is a Linux kernel that runs as an ordinary process and
ships the can, can-raw, can-dev and vcan modules. This helper brings the packages into a
cache (apt-get download + dpkg -x, no root needed), boots that kernel with the host's file
system as its root, loads the modules, creates vcan0, runs one command inside, and returns
its exit code and output. It always cleans up: the kernel's process group is killed on
timeout and the temporary folder is removed.

    python -m can_bus.vcan -- candump -n 1 vcan0
    python -m can_bus.vcan --timeout 120 -- python -m railguard run --interface socketcan --channel vcan0

On a Linux machine with the vcan module, use `ip link add dev vcan0 type vcan && ip link set up vcan0`
instead.
"""
from __future__ import annotations

import argparse
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

PACKAGES = ("user-mode-linux", "kmod", "can-utils")
MODULES = ("drivers/net/can/dev/can-dev.ko", "net/can/can.ko", "net/can/can-raw.ko", "drivers/net/can/vcan.ko")


class SandboxError(RuntimeError):
    """The sandbox could not be set up or booted; the message says what to do."""


@dataclass
class VcanResult:
    returncode: int
    stdout: str
    stderr: str
    console: str
    timed_out: bool = False


def cache_dir() -> Path:
    base = os.environ.get("RAILGUARD_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "railguard")
    return Path(base) / "uml"


def ensure_packages(cache: Path | None = None) -> Path:
    """Download and unpack the Debian packages once; return the unpacked root."""
    cache = cache or cache_dir()
    root = cache / "root"
    if (root / "usr/bin/linux.uml").is_file() and (root / "bin/kmod").is_file() and (root / "usr/bin/candump").is_file():
        return root
    debs = cache / "debs"
    debs.mkdir(parents=True, exist_ok=True)
    if shutil.which("apt-get") is None or shutil.which("dpkg") is None:
        raise SandboxError("apt-get and dpkg are needed to fetch user-mode-linux (Debian or Ubuntu host)")
    proc = subprocess.run(["apt-get", "download", *PACKAGES], cwd=debs, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SandboxError("apt-get download user-mode-linux kmod can-utils failed "
                           f"(run 'apt-get update' first?): {proc.stderr.strip().splitlines()[-1:] or proc.stdout}")
    root.mkdir(parents=True, exist_ok=True)
    for deb in sorted(debs.glob("*.deb")):
        subprocess.run(["dpkg", "-x", str(deb), str(root)], check=True, capture_output=True)
    if not (root / "usr/bin/linux.uml").is_file():
        raise SandboxError(f"linux.uml not found after unpacking into {root}")
    return root


def module_dir(root: Path) -> Path:
    versions = sorted((root / "usr/lib/uml/modules").iterdir())
    if not versions:
        raise SandboxError(f"no kernel modules under {root}/usr/lib/uml/modules")
    return versions[-1] / "kernel"


def init_script(root: Path, work: Path, command: list[str], cwd: Path, env: dict) -> str:
    mods = module_dir(root)
    exports = "\n".join(f"export {k}={shlex.quote(v)}" for k, v in sorted(env.items()))
    loads = "\n".join(f"{work}/insmod {mods / m} || echo 'insmod {m} failed' >> {work}/setup.err" for m in MODULES)
    return f"""#!/bin/sh
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t tmpfs tmpfs /dev/shm 2>/dev/null
{exports}
{loads}
ip link add dev vcan0 type vcan && ip link set up vcan0 || echo 'vcan0 could not be created' >> {work}/setup.err
cd {shlex.quote(str(cwd))}
{shlex.join(command)} > {work}/stdout 2> {work}/stderr < /dev/null
echo $? > {work}/rc
sync
halt -f
"""


def group_members(pgid: int) -> list[int]:
    """Live (not zombie) processes of process group `pgid`, read from /proc."""
    members = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        fields = text[text.rfind(")") + 2:].split()
        if len(fields) > 2 and fields[2] == str(pgid) and fields[0] != "Z":
            members.append(int(stat.parent.name))
    return members


def kill_group(pgid: int, grace: float = 10.0) -> None:
    """SIGKILL the kernel's process group and wait until none of it runs any more.

    A killed UML kernel and its helper processes take a moment to tear down their
    memory; returning before that leaves running processes behind (seen in CI)."""
    deadline = time.monotonic() + grace
    while True:
        try:
            os.killpg(pgid, signal.SIGKILL)
        except ProcessLookupError:
            return
        if not group_members(pgid) or time.monotonic() > deadline:
            return
        time.sleep(0.05)


def run(command: list[str], timeout: float = 120.0, cwd: str | Path | None = None, mem_mb: int = 1024,
        env: dict | None = None) -> VcanResult:
    """Boot the sandbox, run `command` with vcan0 up, return its exit code and output."""
    if not command:
        raise SandboxError("no command given")
    root = ensure_packages()
    work = Path(tempfile.mkdtemp(prefix="railguard-vcan-"))
    try:
        os.symlink(root / "bin/kmod", work / "insmod")
        path = os.pathsep.join([str(Path(sys.executable).parent), str(root / "usr/bin"),
                                "/usr/local/sbin", "/usr/local/bin", "/usr/sbin", "/usr/bin", "/sbin", "/bin"])
        guest_env = {"PATH": path, "HOME": os.environ.get("HOME", "/root"), "LANG": "C.UTF-8",
                     "PYTHONUNBUFFERED": "1", "MPLBACKEND": "Agg"}
        for key in ("CI", "PYTHONPATH", "RAILGUARD_CACHE", "VIRTUAL_ENV"):
            if key in os.environ:
                guest_env[key] = os.environ[key]
        guest_env.update(env or {})
        script = work / "init.sh"
        script.write_text(init_script(root, work, command, Path(cwd or os.getcwd()).resolve(), guest_env))
        script.chmod(0o755)
        argv = [str(root / "usr/bin/linux.uml"), f"mem={mem_mb}M", "rootfstype=hostfs", "rootflags=/", "rw",
                f"uml_dir={work}", f"init={script}", "con=null", "con0=fd:0,fd:1"]
        timed_out = False
        with open(work / "console", "wb") as console:
            proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=console, stderr=subprocess.STDOUT,
                                    start_new_session=True)
            try:
                proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                timed_out = True
            finally:
                kill_group(proc.pid)
                proc.wait()

        def read(name: str) -> str:
            p = work / name
            return p.read_text(errors="replace") if p.exists() else ""

        setup_err = read("setup.err")
        if setup_err and not timed_out:
            raise SandboxError(f"sandbox set-up failed: {setup_err.strip()}")
        rc_text = read("rc").strip()
        rc = int(rc_text) if rc_text.isdigit() else (124 if timed_out else 125)
        return VcanResult(rc, read("stdout"), read("stderr"), read("console"), timed_out)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m can_bus.vcan",
        description="Run COMMAND inside a user-mode Linux with a real SocketCAN vcan0 (no root, no kernel CAN needed).",
        epilog="Example: python -m can_bus.vcan -- candump -n 1 vcan0",
    )
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds before the sandbox is killed (default: %(default)s)")
    ap.add_argument("--mem", type=int, default=1024, help="guest memory in MB (default: %(default)s)")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="the command (after --)")
    args = ap.parse_args(argv)
    cmd = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not cmd:
        ap.error("give a command after --")
    try:
        res = run(cmd, timeout=args.timeout, mem_mb=args.mem)
    except SandboxError as exc:
        print(f"vcan: error: {exc}", file=sys.stderr)
        return 2
    sys.stdout.write(res.stdout)
    sys.stderr.write(res.stderr)
    if res.timed_out:
        print(f"vcan: timed out after {args.timeout} s", file=sys.stderr)
    return res.returncode


if __name__ == "__main__":
    sys.exit(main())
