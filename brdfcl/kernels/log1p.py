"""log1p for the float32 kernels, written inline: the log metric takes it three times per cell.

The OpenCL builtin is SLEEF's log1p on PoCL: a division and double-float arithmetic (~45
instructions) on Debian's PoCL, and an out-of-line call that spills every live vector register on
the pip wheel's PoCL (LLVM 14 does not inline builtins).  This one is a range reduction and one
polynomial, all FMAs, no division: within 1.5 ulp of log1p over every float >= 0 (checked against
float64 in tests/test_log1p.py, on the device too).

    u = 1 + x = 2^k m, m in [sqrt(1/2), sqrt(2))     (k and m from the bits of u)
    f = (m - 1) + (x - (u - 1)) 2^-k                 (the rounding of 1 + x carried into f)
    log1p(x) = k ln 2 + f + f^2 Q(f)                 (Q: a minimax fit of (log1p(f) - f) / f^2)

Special values: +inf -> +inf, NaN -> NaN, x in (-1, 0) is handled too, x = -1 gives -88 (not -inf).
"""
from __future__ import annotations

import numpy as np

LO, HI = float(np.sqrt(0.5) - 1), float(np.sqrt(2) - 1)       # the range of f
LN2_HI, LN2_LO = 0.693145751953125, 1.4286068203094173e-06      # ln 2 = HI + LO, HI exact in 16 bits
SQRT_HALF_BITS = 0x3F3504F3                                    # float bits of sqrt(1/2)
KF_BITS, KF_BIAS = 0x4B400000, 12582912.0                      # as_float(k + KF_BITS) - KF_BIAS = k

# fit(8), rounded to float32: Q(f) = sum COEFFS[i] f^i
COEFFS = (-0.49999988079071045, 0.33333325386047363, -0.25001585483551025, 0.20001985132694244,
          -0.16609056293964386, 0.14181634783744812, -0.1324298083782196, 0.12905502319335938,
          -0.07623060792684555)


def fit(degree: int = 8, nodes: int = 4000, rounds: int = 60) -> tuple[float, ...]:
    """Q's coefficients, float32-rounded: least squares on Chebyshev nodes of [LO, HI], weighted by
    the relative error of log1p, reweighted toward the minimax error (Lawson's iteration)."""
    t = np.cos(np.pi * (np.arange(nodes) + 0.5) / nodes)
    f = (LO + HI) / 2 + (HI - LO) / 2 * t
    f = f[np.abs(f) > 1e-4]                 # Q's formula cancels there; Q is smooth through 0
    q = (np.log1p(f) - f) / f**2
    w = f**2 / np.abs(np.log1p(f))          # an error in Q, relative to log1p
    a = np.vander(f, degree + 1, increasing=True)
    lawson = np.full_like(f, 1.0 / f.size)
    for _ in range(rounds):
        s = w * np.sqrt(lawson)
        c = np.linalg.lstsq(a * s[:, None], q * s, rcond=None)[0]
        lawson *= np.abs((a @ c - q) * w)
        lawson /= lawson.sum()
    return tuple(float(v) for v in c.astype(np.float32))


def log1p_f32(x) -> np.ndarray:
    """The kernels' log1p in numpy float32, operation for operation (FMAs as a multiply and an add
    rounded once, through float64)."""
    x = np.asarray(x, np.float32)
    f32, one = np.float32, np.float32(1)

    def fma(a, b, c):
        return (a.astype(np.float64) * b + c).astype(np.float32)

    with np.errstate(invalid="ignore", over="ignore"):
        u = one + x
        iu = u.view(np.int32)
        k = (iu - np.int32(SQRT_HALF_BITS)) >> 23
        m = (iu - (k << 23)).view(np.float32)
        scale = (np.int32(0x3F800000) - (np.where(k < 126, k, 126).astype(np.int32) << 23)).view(np.float32)
        f = fma(x - (u - one), scale, m - one)
        q = np.full_like(f, f32(COEFFS[-1]))
        for c in COEFFS[-2::-1]:
            q = fma(q, f, f32(c))
        r = fma(f * f, q, f)
        kf = (k + np.int32(KF_BITS)).view(np.float32) - f32(KF_BIAS)
        r = fma(kf, f32(LN2_HI), fma(kf, f32(LN2_LO), r))
        return np.where(np.isposinf(x), x, r)


def c_source(real: str, cond: str, name: str = "brdfcl_log1p") -> str:
    """The OpenCL function for one float type (``float`` or ``floatN``) and its integer type.  Only
    operators and reinterpreting casts, no builtins (the pip PoCL calls fma, min and convert out of
    line); each ``a * b + c`` is one expression, which OpenCL contracts to an FMA."""
    poly = f"{COEFFS[-1]!r}f" if COEFFS[-1] >= 0 else f"(-{-COEFFS[-1]!r}f)"
    for c in COEFFS[-2::-1]:
        poly = f"({poly}) * f {'-' if c < 0 else '+'} {abs(c)!r}f"     # no unary minus: one op each
    return f"""\
inline {real} __attribute__((overloadable)) {name}({real} x)
{{
    const {real} u = 1 + x;
    const {cond} iu = as_{cond}(u);
    const {cond} k = (iu - {SQRT_HALF_BITS:#x}) >> 23;
    const {real} m = as_{real}(iu - (k << 23));
    const {real} scale = as_{real}({0x3F800000:#x} - ((k < 126 ? k : ({cond})126) << 23));
    const {real} f = (x - (u - 1)) * scale + (m - 1);
    const {real} q = {poly};
    const {real} kf = as_{real}(k + {KF_BITS:#x}) - {KF_BIAS!r}f;    /* (float)k, |k| < 2^22 */
    const {real} r = kf * {LN2_HI!r}f + (kf * {LN2_LO!r}f + (f * f * q + f));
    return x == INFINITY ? x : r;
}}
"""
