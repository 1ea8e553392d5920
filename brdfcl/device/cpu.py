"""What the CPU says of itself (``/proc/cpuinfo``), as opposed to what an OpenCL device reports.

A CPU device's report can be wrong (Intel's runtime reports a preferred vector width of one
float on an AVX-512 CPU; the pip PoCL on a Zen 4 reports AVX-512 widths and compiles for a CPU
without them), so decisions that depend on the CPU key on its own flags and name."""
from __future__ import annotations

import platform
from functools import cache


@cache
def _cpuinfo(field: str) -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith(field):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""


def flags() -> str:
    """The CPU's instruction-set flags ("" where the system does not say)."""
    return _cpuinfo("flags") or _cpuinfo("Features")


def name() -> str:
    """The CPU's model name, with its family where it has one (``AMD EPYC (family 26)``)."""
    model = _cpuinfo("model name") or platform.processor() or platform.machine()
    family = _cpuinfo("cpu family")
    return f"{model} (family {family})" if family else model


def native_width(real: str) -> int:
    """Values of ``real`` ("float" or "double") in the CPU's widest vector register: 16 / 8 with
    AVX-512, 8 / 4 with AVX, else 4 / 2 (SSE, NEON)."""
    f = set(flags().split())
    bits = 512 if "avx512f" in f else 256 if "avx" in f else 128
    return bits // (32 if real == "float" else 64)
