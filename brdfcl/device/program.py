"""Building a generated OpenCL program so that a broken kernel cache cannot break a run: the
names the engine (brdfcl.device.engine) builds a program with, from the modules that do each part.

PoCL keeps compiled programs in a cache (``POCL_CACHE_DIR``, default ``~/.cache/pocl``).  A
process that crashed while compiling can leave entries behind that make every later run fail.
So, before the first build of a process, cache entries with an incomplete file
(brdfcl.device.soundness) or with a file that differs from the fingerprint brdfcl took when that
entry last worked (brdfcl.device.fingerprints) are removed from PoCL's cache
(brdfcl.device.poclcache); a program is built and self-tested inside a guard that moves it to a
new cache key after a run died there (brdfcl.device.crashguard); a program whose kernels are
missing, or that fails the caller's check, is built again under a different cache key (the
engine, with brdfcl.device.build's options); and a program that passed its self-test is kept as a
device binary for the next process (brdfcl.device.binaries).
"""
from __future__ import annotations

from brdfcl.device.binaries import KEEP_BINARIES, binary_path, forget_binary, keep_binary, load_binary
from brdfcl.device.build import ABI_WARNING, BUILD_OPTIONS, KERNELS, build, build_log, build_options
from brdfcl.device.crashguard import crash_guard, keep_attempt
from brdfcl.device.errors import ProgramError
from brdfcl.device.poclcache import pocl_cache_dir, remember_pocl_cache, repair_pocl_cache
from brdfcl.device.soundness import sound_bitcode, sound_elf

__all__ = ["ABI_WARNING", "BUILD_OPTIONS", "KEEP_BINARIES", "KERNELS", "ProgramError", "binary_path", "build",
           "build_log", "build_options", "crash_guard", "forget_binary", "keep_attempt", "keep_binary",
           "load_binary", "pocl_cache_dir", "remember_pocl_cache", "repair_pocl_cache", "sound_bitcode",
           "sound_elf"]
