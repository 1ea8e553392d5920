"""ABC microfacet distribution (Low, Kronander, Ynnerman, Unger 2012, BRDF models for accurate and
efficient rendering of glossy surfaces, section 5, the microfacet model's D, of the form of their ABC
smooth-surface spectrum): D = N (1 + B (1 - cos th))^-C.

B sets the width (near the peak 1 - cos th ~ th^2 / 2, so B / 2 plays 1 / alpha^2), C the tail
(D ~ (B (1 - cos th))^-C far from it).  Named ``abc`` among the distributions; the diffraction lobe's
``abc`` is the power spectrum of psd/abc.py (the registry is per kind: ``abc:smith:schlick`` is this
one, ``diffraction:abc`` that one).  1 - cos th is written sin^2 th / (1 + cos th) =
tan^2 th cos^2 th / (1 + cos th), exact at the peak in float.

N = 1 / M normalises D cos th over the hemisphere: with Y = 1 + B, y = 1 + B (1 - mu),

    M = 2 pi int_0^1 mu (1 + B (1 - mu))^-C dmu = (2 pi / B^2) int_1^Y (Y - y) y^-C dy
      = (2 pi / B^2) (Y g(1 - C) - g(2 - C)),   g(k) = int_1^Y y^(k-1) dy = expm1(k l) / k = l E(k l),

l = ln(1 + B), E(x) = expm1(x) / x (E(0) = 1; exact near 0 since expm1 is), so C = 1 and C = 2 (where
the closed form has its removable singularities, the logarithmic cases) are as accurate as any other
C.  N and its derivatives are computed on the host (``abc_consts``):
dM/dB = -2 M / B + (2 pi / B^2) g(1 - C) and dM/dC = (2 pi / B^2)(g'(2 - C) - Y g'(1 - C)),
g'(k) = l^2 E'(k l), E' from its series near 0.

Bounds: B 0.1..1e8 (B = 1e8 is as sharp as GGX's alpha = 1.4e-4; B < 1 nearly uniform), C 0.25..8,
which holds the published fits (C ~0.5..6, B up to ~1e5).
"""
from __future__ import annotations

import numpy as np

from brdfcl.model.terms.base import Param, Term, register
from brdfcl.model.terms.ndf.gtr import expm1_over_x

SHARPNESS = Param("B", 0.1, 1e8, 200.0, log=True, search=(1.0, 1e6),
                  doc="ABC sharpness (B / 2 ~ 1 / alpha^2 at the peak; 1e8 is a mirror at MERL's resolution)")
TAIL = Param("C", 0.25, 8.0, 2.0, search=(0.5, 6.0),
             doc="ABC tail exponent: D ~ (B (1 - cos th))^-C in the tail")

_N_SERIES = 18


def d_expm1_over_x(x):
    """E'(x) = (x e^x - expm1(x)) / x^2 = sum n x^(n-1) / (n+1)!, from the series for |x| < 1/2."""
    x = np.asarray(x, dtype=np.float64)
    small = np.abs(x) < 0.5
    xs = np.where(small, x, 0.0)
    series = np.zeros_like(x)
    fact = 1.0
    for n in range(1, _N_SERIES):
        fact *= n + 1
        series = series + n * xs ** (n - 1) / fact
    safe = np.where(small, 1.0, x)
    return np.where(small, series, (safe * np.exp(safe) - np.expm1(safe)) / (safe * safe))


def abc_consts(B, C):
    """({'N': N}, {'N': {'B': dN/dB, 'C': dN/dC}}), float64."""
    B, C = np.asarray(B, dtype=np.float64), np.asarray(C, dtype=np.float64)
    ell = np.log1p(B)
    Y = 1.0 + B
    g1, g2 = ell * expm1_over_x((1.0 - C) * ell), ell * expm1_over_x((2.0 - C) * ell)
    dg1, dg2 = ell * ell * d_expm1_over_x((1.0 - C) * ell), ell * ell * d_expm1_over_x((2.0 - C) * ell)
    k = 2.0 * np.pi / (B * B)
    M = k * (Y * g1 - g2)
    dM_dB = -2.0 * M / B + k * g1
    dM_dC = k * (dg2 - Y * dg1)
    N = 1.0 / M
    return {"N": N}, {"N": {"B": -N * dM_dB / M, "C": -N * dM_dC / M}}


def abc(B, C, N):
    from sympy import exp

    from brdfcl.model.terms.symbols import ch, log1p, t2
    one_minus_cos = t2 * ch**2 / (1 + ch)
    return N * exp(-C * log1p(B * one_minus_cos))


register(Term("ndf", "abc", (SHARPNESS, TAIL), abc, host=("N",), host_consts=abc_consts,
              doc="ABC microfacet distribution (1 + B (1 - cos th))^-C",
              cite="Low, Kronander, Ynnerman, Unger 2012, BRDF models for accurate and efficient "
                   "rendering of glossy surfaces, section 5 (microfacet model)"))
