"""Building a generated OpenCL program so that a broken kernel cache cannot break a run.

PoCL keeps compiled programs in a cache (``POCL_CACHE_DIR``, default
``~/.cache/pocl``).  A process that crashed while compiling can leave entries
behind that make every later run fail: a truncated ``program.bc`` (the kernels
are then missing: ``INVALID_KERNEL_NAME``) or a truncated kernel library
(PoCL aborts the whole process when it cannot load it).  So, before the first
build of a process, broken kernel libraries are removed from PoCL's cache (they
are recompiled on demand), and a program whose kernels are missing, or that
fails the caller's check, is built again under a different cache key.
"""
from __future__ import annotations

import os
import shutil
import struct
from pathlib import Path

import pyopencl as cl

from .device import DeviceError

KERNELS = ("loss", "grad", "jtj", "errors", "predict")
BUILD_OPTIONS = ["-cl-mad-enable"]
ABI_WARNING = "changes the ABI"     # LLVM, when vector arguments are wider than the target
_REPAIRED: set = set()


class ProgramError(DeviceError):
    """A program that cannot be built or used on a device; the message is one line."""


def pocl_cache_dir(platform) -> Path | None:
    """PoCL's kernel cache for a PoCL platform (None for other platforms)."""
    if "portable computing" not in platform.name.lower():
        return None
    base = os.environ.get("POCL_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = os.path.join(xdg, "pocl")
    return Path(base) / "kcache" if (Path(base) / "kcache").is_dir() else Path(base)


def sound_elf(path: Path) -> bool:
    """True when a file is a complete 64- or 32-bit ELF object: magic, and every header table
    inside the file (a truncated or overwritten library fails this)."""
    try:
        size = path.stat().st_size
        with open(path, "rb") as f:
            head = f.read(64)
    except OSError:
        return False
    if len(head) < 52 or head[:4] != b"\x7fELF" or head[4] not in (1, 2) or head[5] not in (1, 2):
        return False
    end = "<" if head[5] == 1 else ">"
    if head[4] == 2:
        if len(head) < 64:
            return False
        phoff, shoff = struct.unpack_from(end + "QQ", head, 32)
        phentsize, phnum, shentsize, shnum = struct.unpack_from(end + "HHHH", head, 54)
    else:
        phoff, shoff = struct.unpack_from(end + "II", head, 28)
        phentsize, phnum, shentsize, shnum = struct.unpack_from(end + "HHHH", head, 42)
    return phoff + phentsize * phnum <= size and shoff + shentsize * shnum <= size


def sound_bitcode(path: Path) -> bool:
    """True when a file is complete LLVM bitcode: its magic, then top-level blocks whose
    recorded lengths add up to the file's length (a truncated file fails this)."""
    try:
        data = path.read_bytes()
    except OSError:
        return False
    if data[:4] == b"\xde\xc0\x17\x0b":                      # bitcode wrapper header
        if len(data) < 20:
            return False
        offset, size = struct.unpack_from("<II", data, 8)
        if offset + size > len(data):
            return False
        data = data[offset:offset + size]
    if data[:4] != b"BC\xc0\xde":
        return False
    bits = int.from_bytes(data, "little")
    total, pos = 8 * len(data), 32

    def read(n):
        nonlocal pos
        if pos + n > total:
            raise EOFError
        v = (bits >> pos) & ((1 << n) - 1)
        pos += n
        return v

    def vbr(n):
        v, shift = 0, 0
        while True:
            chunk = read(n)
            v |= (chunk & ((1 << (n - 1)) - 1)) << shift
            shift += n - 1
            if not chunk >> (n - 1):
                return v
    blocks = 0
    try:
        while total - pos >= 32 and bits >> pos:               # zero words may pad the end
            if read(2) != 1:                                   # top level holds only blocks
                return False
            blocks += 1
            vbr(8)                                             # block id
            vbr(4)                                             # abbreviation width
            pos = -(-pos // 32) * 32
            words = read(32)                                   # block length in 32-bit words
            pos += 32 * words
        return blocks > 0 and pos <= total and not bits >> pos
    except EOFError:
        return False


def _sound(path: Path) -> bool:
    return sound_bitcode(path) if path.suffix == ".bc" else sound_elf(path)


def repair_pocl_cache(platform, log=None) -> list:
    """Remove cache entries whose program bitcode or kernel libraries are incomplete (PoCL
    rebuilds them); once per process and cache.  Returns the removed entry folders."""
    root = pocl_cache_dir(platform)
    if root is None or root in _REPAIRED or not root.is_dir():
        return []
    _REPAIRED.add(root)
    removed = []
    files = [(p, p.parent) for p in root.glob("*/*/*.bc")] + [(p, p.parents[2]) for p in root.glob("*/*/*/*/*.so")]
    for path, entry in files:
        if entry in removed or _sound(path):
            continue
        shutil.rmtree(entry, ignore_errors=True)
        removed.append(entry)
        if log:
            log(f"brdfcl: removed a broken PoCL kernel-cache entry ({path.name}): {entry}")
    return removed


def build(ctx, device, source: str, attempt: int = 0):
    """(program, {name: kernel}) for a source; ``attempt`` > 0 builds it under a new cache key."""
    if attempt:
        # PoCL's cache key is a hash of the source: a marker line gives a fresh, separate entry.
        source = f"/* brdfcl: rebuilt past a broken cache entry, attempt {attempt} */\n{source}"
    try:
        program = cl.Program(ctx, source).build(options=BUILD_OPTIONS, devices=[device])
        kernels = {k: cl.Kernel(program, k) for k in KERNELS}
    except cl.Error as e:
        raise ProgramError(f"OpenCL build failed on {device.name}: {_what(e)}") from None
    return program, kernels


def build_log(program, device) -> str:
    try:
        return program.get_build_info(device, cl.program_build_info.LOG) or ""
    except cl.Error:
        return ""


def _what(e) -> str:
    """A pyopencl error as one readable line (its default str can be a bare object repr)."""
    rec = e.args[0] if e.args else None
    what = getattr(rec, "what", None)
    text = what() if callable(what) else (what or str(e))
    return " ".join(str(text).split())[:300]
