"""Special functions that OpenCL has and the shading languages brdfcl prints into lack (GLSL,
Dr.Jit), written once and printed into each.

* ``erfc``: Numerical Recipes' erfcc (Press et al., Numerical Recipes in C, 2nd ed., sec. 6.2), a
  Chebyshev fit with relative error < 1.2e-7 everywhere, its coefficients those of the float32
  kernels' erfc (brdfcl.kernels.inline_math): with z = |x|, t = 1 / (1 + z / 2),
  erfc(z) = t exp(-z^2 + c0 + t (c1 + t (c2 + ... + t c9))), and erfc(-z) = 2 - erfc(z).
* ``log1p``: ln(1 + x) accurate near 0 from ln alone: u = 1 + x, then x where u == 1, else
  ln(u) x / (u - 1) (the rounding of u cancels).
"""
from __future__ import annotations

from brdfcl.kernels.inline_math import ERFCC


def erfcc_exponent(t: str = "t", z: str = "z") -> str:
    """-z^2 + c0 + t (c1 + t (... + t c9)) as text, in any C-like syntax or Python."""
    inner = repr(ERFCC[-1])
    for c in reversed(ERFCC[1:-1]):
        inner = f"{c!r} + {t} * ({inner})"
    return f"-{z} * {z} + {ERFCC[0]!r} + {t} * ({inner})"
