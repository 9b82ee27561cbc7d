"""The secured-frame functions in C (fmu/c/secoc/, issue 39) as a shared library with a ctypes
face: the C side of the bus's authentication, checked against can_bus/secoc.py (tests) and
timed (benchmarks/bench_secoc.py), ready for the nodes that will carry frames in C (issue
42's network FMUs). libcrypto (OpenSSL 3) provides AES-CMAC: `apt-get install libssl-dev`.
"""
from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path
from typing import Optional

from .build import C_DIR, CFLAGS, BuildError, compiler

SECOC_DIR = C_DIR / "secoc"
VERDICTS = ("ok", "wrong_length", "stale_freshness", "bad_mac", "error")   # RG_SECOC_* in order


def build(out_dir: Path) -> Path:
    """Compile rg_secoc.c into `out_dir`/librg_secoc.so (warnings are errors)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    output = out_dir / "librg_secoc.so"
    cmd = [compiler(), *CFLAGS, "-shared", f"-I{SECOC_DIR}", str(SECOC_DIR / "rg_secoc.c"), "-o", str(output), "-lcrypto"]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise BuildError(f"compiling {output.name} failed (libcrypto: apt-get install libssl-dev):\n{res.stderr.strip()}")
    return output


class SecocC:
    """The C functions, called through ctypes."""

    def __init__(self, library: Path) -> None:
        lib = ctypes.CDLL(str(library))
        u8p, u64 = ctypes.c_char_p, ctypes.c_uint64
        lib.rg_secoc_authenticator.argtypes = [u8p, ctypes.c_uint16, u8p, u64, ctypes.c_char_p]
        lib.rg_secoc_protect.argtypes = [u8p, ctypes.c_uint16, u8p, u64, ctypes.c_char_p]
        lib.rg_secoc_rebuild.argtypes = [ctypes.c_int, u64, ctypes.c_uint32]
        lib.rg_secoc_rebuild.restype = u64
        lib.rg_secoc_check.argtypes = [u8p, ctypes.c_uint16, u8p, ctypes.c_size_t, ctypes.c_int, u64,
                                       ctypes.POINTER(u64)]
        self.lib = lib

    def protect(self, key: bytes, frame_id: int, payload: bytes, fv: int) -> bytes:
        out = ctypes.create_string_buffer(20)
        if self.lib.rg_secoc_protect(key, frame_id, payload, fv, out) != 0:
            raise RuntimeError("rg_secoc_protect failed (libcrypto)")
        return out.raw

    def rebuild(self, newest: Optional[int], low: int) -> int:
        return self.lib.rg_secoc_rebuild(newest is not None, newest or 0, low)

    def check(self, key: bytes, frame_id: int, data: bytes, newest: Optional[int]) -> tuple[str, Optional[int]]:
        fv = ctypes.c_uint64(0)
        verdict = VERDICTS[self.lib.rg_secoc_check(key, frame_id, data, len(data), newest is not None, newest or 0,
                                                   ctypes.byref(fv))]
        return verdict, (fv.value if verdict == "ok" else None)
