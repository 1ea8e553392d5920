"""Building a generated OpenCL program from source: its kernels, its build options, its log.

One place says which options build a program, so that a program built from source and one
loaded from a kept binary (brdfcl.device.binaries) are built alike; which kernels it holds comes
from the generated source's model (brdfcl.kernels.codegen.kernel_names).  A failed build is one
short ProgramError line (the whole log goes to brdfcl's build logs, brdfcl.device.buildlog), and
the failed program is released at once.
"""
from __future__ import annotations

import gc
import warnings

import pyopencl as cl

from brdfcl.device import buildlog
from brdfcl.device.errors import ProgramError
from brdfcl.kernels.codegen import KERNELS

BUILD_OPTIONS = ["-cl-mad-enable"]
ABI_WARNING = "changes the ABI"     # LLVM, when vector arguments are wider than the target


def build_options(attempt: int) -> list[str]:
    """The build options of cache-key ``attempt`` (brdfcl.device.crashguard): BUILD_OPTIONS, and
    for ``attempt`` > 0 a define that gives the program a separate PoCL cache entry."""
    options = list(BUILD_OPTIONS)
    if attempt:
        # PoCL's cache key hashes the preprocessed source (comments are gone) and the build
        # options: a define in the options gives a fresh, separate entry.
        options.append(f"-DBRDFCL_CACHE_KEY={attempt}")
    return options


def build(ctx, device, source: str, attempt: int = 0, names: tuple[str, ...] = KERNELS):
    """(program, {name: kernel} of ``names``) for a source; ``attempt`` > 0 builds it under a new
    cache key."""
    options = build_options(attempt)
    program = cl.Program(ctx, source)
    try:
        with warnings.catch_warnings():         # Intel's compiler always logs; failures are ours to tell
            warnings.simplefilter("ignore", cl.CompilerWarning)
            program.build(options=options, devices=[device])
        kernels = {k: cl.Kernel(program, k) for k in names}
    except cl.Error as e:
        f = buildlog.failure(e, f"build on {device.name}, options {' '.join(options)}")
        failed = ProgramError(buildlog.line(f"cannot build on {device.name}: ", f.cause, f.log), f.cause, f.log)
    else:
        return program, kernels
    del program
    gc.collect()                # release the failed program now: PoCL cannot tear down its IR later
    raise failed


def build_log(program, device) -> str:
    """The compiler's log of a built program on a device ("" when there is none)."""
    try:
        return program.get_build_info(device, cl.program_build_info.LOG) or ""
    except cl.Error:
        return ""
