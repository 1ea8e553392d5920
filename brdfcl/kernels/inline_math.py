"""log1p, log, exp and erfc for the float32 kernels, written inline.

The OpenCL builtins are SLEEF's on PoCL: log1p and log a division and double-float arithmetic
(~45 instructions), erfc about ten times an exp, and on the pip wheel's PoCL (LLVM 14 does not
inline builtins) out-of-line calls that spill every live vector register.  The log metric takes
log1p three times per cell; the GTR and ABC lobes' Smith quadratures a log and an exp per node (20
each per cell); the Beckmann Smith term an erfc per direction.  log1p, log and exp are a range
reduction and one polynomial each, all FMAs, no division; erfc is one division, a polynomial and
two of these exps.  float64 is the ground truth (tests/test_inline_math.py, on every OpenCL device
too): log1p within 1.5 ulp for x >= 0, log within 1.5 ulp for normal x > 0, exp within 1.3 ulp,
erfc within 8 ulp wherever it is a normal float (Numerical Recipes' fit itself within 1.1e-7).

    log1p(x): u = 1 + x = 2^k m, m in [sqrt(1/2), sqrt(2))        (k, m from the bits of u)
              f = (m - 1) + (x - (u - 1)) 2^-k                    (the rounding of 1 + x carried)
              log1p(x) = k ln 2 + f + f^2 Q(f)                    (Q: minimax, (log1p(f) - f) / f^2)
    log(x):   the same with u = x, nothing to carry
    exp(x):   k = round(x / ln 2), r = x - k ln 2 in [-ln2/2, ln2/2]
              exp(x) = 2^k (1 + r + r^2 P(r))                     (P: minimax, (e^r - 1 - r) / r^2)

    erfc(x):  z = |x|, t = 1 / (1 + z / 2), zh = z with its 12 low mantissa bits cleared
              erfc(z) = t exp(-zh^2) exp(c0 + t (c1 + ... + t c9) - (z - zh)(z + zh))
              erfc(-z) = 2 - erfc(z)
              (Numerical Recipes' erfcc, Press et al., Numerical Recipes in C, 2nd ed., sec. 6.2:
              a Chebyshev fit of relative error < 1.2e-7; zh^2 is exact, so the large part of the
              exponent is not rounded and the second exp's argument stays small)

Special values: log1p(inf) = log(inf) = exp(inf) = inf, log(0) = -inf, exp(-inf) = 0, NaN stays
NaN, log of a negative is NaN, as the builtins.  Where they differ (outside what the kernels take):
log1p(-1) is -88 and log1p(x < -1) a finite number, not -inf and NaN; log1p(-0) is +0; the log of
a subnormal is about -88 (the truth down to -103); exp below -104 is 0; erfc above 10.2 is 0 (the
truth a subnormal below 1e-45 from 10.05).
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

NAMES = ("log1p", "log", "exp", "erfc")       # the builtins the float32 kernels take from here

LN2_HI, LN2_LO = 0.693145751953125, 1.4286068203094173e-06      # ln 2 = HI + LO, HI exact in 16 bits
INV_LN2 = 1.4426950408889634                                   # 1 / ln 2
SQRT_HALF_BITS = 0x3F3504F3                                    # float bits of sqrt(1/2)
MAGIC = 12582912.0                                             # 1.5 * 2^23: x + MAGIC rounds x to an integer
MAGIC_BITS = 0x4B400000                                        # its bits: as_int(k + MAGIC) - MAGIC_BITS = k
EXP_HI, EXP_LO = 88.8, -104.0                                  # exp is inf above, 0 below
HIGH_BITS = 0xFFFFF000                                         # a float's sign, exponent and 11 mantissa bits

# fit_log(8) and fit_exp(4), rounded to float32
LOG_COEFFS = (-0.49999988079071045, 0.33333325386047363, -0.25001585483551025, 0.20001985132694244,
              -0.16609056293964386, 0.14181634783744812, -0.1324298083782196, 0.12905502319335938,
              -0.07623060792684555)
EXP_COEFFS = (0.4999999403953552, 0.1666652113199234, 0.04166838899254799, 0.008368710055947304,
              0.0013814610429108143)

ERFCC = (-1.26551223, 1.00002368, 0.37409196, 0.09678418, -0.18628806, 0.27886807, -1.13520398,
         1.48851587, -0.82215223, 0.17087277)
"""Numerical Recipes' erfcc coefficients c0 .. c9 (also printed into the GLSL and Dr.Jit exports)."""


def _lawson(x: np.ndarray, q: np.ndarray, w: np.ndarray, degree: int, rounds: int = 60) -> tuple[float, ...]:
    """Coefficients of the polynomial closest to ``q`` at ``x`` in the weighted max norm (least
    squares reweighted toward the minimax error, Lawson's iteration), float32-rounded."""
    a = np.vander(x, degree + 1, increasing=True)
    lawson = np.full_like(x, 1.0 / x.size)
    for _ in range(rounds):
        s = w * np.sqrt(lawson)
        c = np.linalg.lstsq(a * s[:, None], q * s, rcond=None)[0]
        lawson *= np.abs((a @ c - q) * w)
        lawson /= lawson.sum()
    return tuple(float(v) for v in c.astype(np.float32))


def _nodes(lo: float, hi: float, n: int = 4000) -> np.ndarray:
    x = (lo + hi) / 2 + (hi - lo) / 2 * np.cos(np.pi * (np.arange(n) + 0.5) / n)
    return x[np.abs(x) > 1e-4]              # the quotients cancel there; they are smooth through 0


def fit_log(degree: int = 8) -> tuple[float, ...]:
    """Q of log1p(f) = f + f^2 Q(f) on f in [sqrt(1/2) - 1, sqrt(2) - 1], relative error of log1p."""
    f = _nodes(np.sqrt(0.5) - 1, np.sqrt(2) - 1)
    return _lawson(f, (np.log1p(f) - f) / f**2, f**2 / np.abs(np.log1p(f)), degree)


def fit_exp(degree: int = 4) -> tuple[float, ...]:
    """P of e^r = 1 + r + r^2 P(r) on r in [-ln2/2, ln2/2], relative error of e^r."""
    r = _nodes(-np.log(2) / 2, np.log(2) / 2)
    return _lawson(r, (np.exp(r) - 1 - r) / r**2, r**2 / np.exp(r), degree)


# ---- numpy twins: the kernels' arithmetic operation for operation (an FMA through float64) ---

def _fma(a, b, c):
    return (np.asarray(a, np.float64) * b + c).astype(np.float32)


def _horner(coeffs, x):
    q = np.full_like(x, np.float32(coeffs[-1]))
    for c in coeffs[-2::-1]:
        q = _fma(q, x, np.float32(c))
    return q


def _log_parts(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k, m, k as float) with u = 2^k m, m in [sqrt(1/2), sqrt(2))."""
    iu = u.view(np.int32)
    k = (iu - np.int32(SQRT_HALF_BITS)) >> 23
    m = (iu - (k << 23)).view(np.float32)
    kf = (k + np.int32(MAGIC_BITS)).view(np.float32) - np.float32(MAGIC)
    return k, m, kf


def _log_tail(kf, f):
    r = _fma(f * f, _horner(LOG_COEFFS, f), f)
    return _fma(kf, np.float32(LN2_HI), _fma(kf, np.float32(LN2_LO), r))


def log1p_f32(x) -> np.ndarray:
    """The kernels' log1p in numpy float32."""
    x = np.asarray(x, np.float32)
    one = np.float32(1)
    with np.errstate(invalid="ignore", over="ignore"):
        u = one + x
        k, m, kf = _log_parts(u)
        scale = (np.int32(0x3F800000) - (np.where(k < 126, k, 126).astype(np.int32) << 23)).view(np.float32)
        r = _log_tail(kf, _fma(x - (u - one), scale, m - one))
        return np.where(np.isposinf(x), x, r)


def log_f32(x) -> np.ndarray:
    """The kernels' log in numpy float32."""
    x = np.asarray(x, np.float32)
    with np.errstate(invalid="ignore", over="ignore"):
        _, m, kf = _log_parts(x)
        r = _log_tail(kf, m - np.float32(1))
        return np.where(np.isposinf(x), x, np.where(x > 0, r, np.where(x == 0, -np.inf, np.nan))).astype(np.float32)


def exp_f32(x) -> np.ndarray:
    """The kernels' exp in numpy float32."""
    x = np.asarray(x, np.float32)
    f32 = np.float32
    with np.errstate(invalid="ignore", over="ignore"):
        t = _fma(x, f32(INV_LN2), f32(MAGIC))
        k = t.view(np.int32) - np.int32(MAGIC_BITS)
        kf = t - f32(MAGIC)
        r = _fma(-kf, f32(LN2_LO), _fma(-kf, f32(LN2_HI), x))
        p = _fma(r * r, _horner(EXP_COEFFS, r), r + f32(1))
        k1 = k >> 1
        s1 = ((k1 + 127) << 23).astype(np.int32).view(np.float32)
        s2 = ((k - k1 + 127) << 23).astype(np.int32).view(np.float32)
        y = p * s1 * s2
        return np.where(x > EXP_HI, f32(np.inf), np.where(x < EXP_LO, f32(0), y)).astype(np.float32)


def erfc_f32(x) -> np.ndarray:
    """The kernels' erfc in numpy float32."""
    x = np.asarray(x, np.float32)
    f32 = np.float32
    with np.errstate(invalid="ignore", over="ignore"):
        z = (x.view(np.int32) & np.int32(0x7FFFFFFF)).view(np.float32)
        zh = (z.view(np.uint32) & np.uint32(HIGH_BITS)).view(np.float32)
        t = f32(1) / _fma(z, f32(0.5), f32(1))
        q = _fma(-(z - zh), z + zh, _fma(_horner(ERFCC[1:], t), t, f32(ERFCC[0])))
        r = np.where(np.isposinf(z), f32(0), t * exp_f32(q) * exp_f32(-(zh * zh)))
        return np.where(x < 0, f32(2) - r, r).astype(np.float32)


TWINS: dict[str, Callable] = {"log1p": log1p_f32, "log": log_f32, "exp": exp_f32, "erfc": erfc_f32}


# ---- OpenCL ----------------------------------------------------------------------------------

def _poly(coeffs, x: str) -> str:
    """Horner's scheme as one expression, each step ``a * x + c`` (OpenCL contracts it to an FMA);
    signs written as operators, never a unary minus."""
    lead = coeffs[-1]
    p = f"{lead!r}f" if lead >= 0 else f"(0.0f - {-lead!r}f)"
    for c in coeffs[-2::-1]:
        p = f"({p}) * {x} {'-' if c < 0 else '+'} {abs(c)!r}f"
    return p


def c_source(real: str, cond: str) -> str:
    """brdfcl_log1p, brdfcl_log, brdfcl_exp and brdfcl_erfc for one float type (``float`` or ``floatN``) and its
    integer type: only operators and reinterpreting casts, no builtin (the pip PoCL calls fma, min
    and convert out of line)."""
    parts = f"""\
    const {cond} k = (iu - {SQRT_HALF_BITS:#x}) >> 23;
    const {real} m = as_{real}(iu - (k << 23));
    const {real} kf = as_{real}(k + {MAGIC_BITS:#x}) - {MAGIC!r}f;    /* (float)k, |k| < 2^22 */"""
    tail = f"kf * {LN2_HI!r}f + (kf * {LN2_LO!r}f + (f * f * ({_poly(LOG_COEFFS, 'f')}) + f))"
    head = f"inline {real} __attribute__((overloadable))"
    return f"""\
{head} brdfcl_log1p({real} x)
{{
    const {real} u = 1 + x;
    const {cond} iu = as_{cond}(u);
{parts}
    const {real} scale = as_{real}(0x3f800000 - ((k < 126 ? k : ({cond})126) << 23));
    const {real} f = (x - (u - 1)) * scale + (m - 1);
    const {real} r = {tail};
    return x == INFINITY ? x : r;
}}

{head} brdfcl_log({real} x)
{{
    const {cond} iu = as_{cond}(x);
{parts}
    const {real} f = m - 1;
    const {real} r = {tail};
    return x == INFINITY ? x : (x > 0 ? r : (x == 0 ? ({real})(-INFINITY) : ({real})NAN));
}}

{head} brdfcl_exp({real} x)
{{
    const {real} t = x * {INV_LN2!r}f + {MAGIC!r}f;
    const {cond} k = as_{cond}(t) - {MAGIC_BITS:#x};
    const {real} kf = t - {MAGIC!r}f;
    const {real} r = (0.0f - kf) * {LN2_LO!r}f + ((0.0f - kf) * {LN2_HI!r}f + x);
    const {real} p = r * r * ({_poly(EXP_COEFFS, 'r')}) + (r + 1);
    const {cond} k1 = k >> 1;                                   /* 2^k in two factors: k up to 254 */
    const {real} y = p * as_{real}((k1 + 127) << 23) * as_{real}((k - k1 + 127) << 23);
    return x > {EXP_HI!r}f ? ({real})INFINITY : (x < {EXP_LO!r}f ? ({real})0 : y);
}}

{head} brdfcl_erfc({real} x)
{{
    const {real} z = as_{real}(as_{cond}(x) & 0x7fffffff);
    const {real} zh = as_{real}(as_{cond}(z) & ({cond})(-4096));    /* HIGH_BITS: zh * zh exact */
    const {real} t = 1 / (z * 0.5f + 1);
    const {real} q = (0.0f - (z - zh)) * (z + zh) + (({_poly(ERFCC[1:], 't')}) * t + {ERFCC[0]!r}f);
    const {real} e = t * brdfcl_exp(q) * brdfcl_exp(0.0f - zh * zh);
    const {real} r = z == INFINITY ? ({real})0 : e;                /* inf - inf in q */
    return x < 0 ? 2 - r : r;
}}
"""
