"""Device binaries of programs that passed their self-test, kept in brdfcl's cache
(``programs/*.bin``) so that the next process loads them instead of building from source.

A kept binary spares the runtime's own cache lookup, which preprocesses the whole source first
(for PoCL, a large part of a second a program).  A binary is keyed by everything that could make it wrong
(source, build options, device, driver, platform); one that does not load is removed, and only
the newest KEEP_BINARIES are kept.
"""
from __future__ import annotations

import hashlib
import os
import warnings
from pathlib import Path

import pyopencl as cl

from brdfcl._cache import cache_dir
from brdfcl.device.build import build_options
from brdfcl.kernels.codegen import KERNELS

KEEP_BINARIES = 32
"""Program binaries kept in brdfcl's cache (the newest; each some 0.2-1 MB)."""


def binary_path(device, source: str, attempt: int = 0) -> Path:
    """Where brdfcl keeps the device binary of a program: keyed by the source, the build options
    and the device, its driver and its platform (a new runtime or driver builds afresh)."""
    p = device.platform
    ident = "\0".join((source, " ".join(build_options(attempt)), device.name, device.version, device.driver_version,
                       p.name, p.version))
    return cache_dir() / "programs" / f"{hashlib.sha1(ident.encode()).hexdigest()[:32]}.bin"


def load_binary(ctx, device, source: str, attempt: int = 0, names: tuple[str, ...] = KERNELS):
    """(program, {name: kernel} of ``names``) from the binary a successful build left (`keep_binary`), None when
    there is none or it does not load (then removed), built with the same options as from source."""
    path = binary_path(device, source, attempt)
    try:
        binary = path.read_bytes()
    except OSError:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", cl.CompilerWarning)
            program = cl.Program(ctx, [device], [binary]).build(options=build_options(attempt), devices=[device])
        return program, {k: cl.Kernel(program, k) for k in names}
    except (cl.Error, ValueError):
        forget_binary(device, source, attempt)
        return None


def keep_binary(program, device, source: str, attempt: int = 0) -> None:
    """Keep the device binary of a program that passed its self-test; the oldest beyond
    KEEP_BINARIES are removed.  An unwritable cache keeps nothing."""
    path = binary_path(device, source, attempt)
    try:
        binary = program.get_info(cl.program_info.BINARIES)[program.devices.index(device)]
        if not binary:
            return
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
        tmp.write_bytes(binary)
        os.replace(tmp, path)
        kept = sorted(path.parent.glob("*.bin"), key=lambda f: f.stat().st_mtime, reverse=True)
        for old in kept[KEEP_BINARIES:]:
            old.unlink(missing_ok=True)
    except (OSError, cl.Error, ValueError):
        pass


def forget_binary(device, source: str, attempt: int = 0) -> None:
    """Remove a kept binary (it failed to load or its self-test)."""
    try:
        binary_path(device, source, attempt).unlink(missing_ok=True)
    except OSError:
        pass
