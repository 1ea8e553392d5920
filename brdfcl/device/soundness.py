"""Whether a file of PoCL's kernel cache is complete, read from its own structure.

A process that crashed while PoCL compiled can leave a truncated ``program.bc`` (the kernels are
then missing: ``INVALID_KERNEL_NAME``) or a truncated kernel library (PoCL aborts the whole
process when it cannot load it).  Both show in the file's structure: an ELF object's header
tables must lie inside the file, LLVM bitcode's top-level blocks must add up to its length.
Damage that keeps the length is left to the fingerprints (brdfcl.device.fingerprints).
"""
from __future__ import annotations

import struct
from pathlib import Path


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


def sound(path: Path) -> bool:
    """True when a cache file is complete: bitcode (``*.bc``) or else an ELF kernel library."""
    return sound_bitcode(path) if path.suffix == ".bc" else sound_elf(path)
