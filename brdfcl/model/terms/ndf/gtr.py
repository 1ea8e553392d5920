"""Generalised Trowbridge-Reitz, GTR (Burley 2012, Physically-based shading at Disney, eq. 4 with
its corrected normalisation, appendix B.2):

    D = c / (alpha^2 cos^2 th + sin^2 th)^gamma,
    c = (gamma - 1)(alpha^2 - 1) / (pi (1 - alpha^(2 - 2 gamma))),

(with u = cos^2 th, 2 pi int D cos th sin th dth = pi c int_0^1 (1 + (alpha^2 - 1) u)^-gamma du = 1).
gamma = 2 is GGX, gamma -> 1 Burley's GTR1 (Berry), gamma < 2 a heavier tail: D(90 deg) / D(0) =
alpha^(2 gamma).  The slope distribution is not shape-invariant (D cos^4 th = K (1 + tan^2)^(gamma-2)
(1 + tan^2 / alpha^2)^-gamma), so its Smith Lambda depends on alpha, gamma and theta_o
(shadowing/smith_gtr.py).

Written as D = K / (cos^2 th (1 + tan^2 th / alpha^2))^gamma with K = c alpha^(-2 gamma) = D(0), so
that the kernel only raises a number >= 1 to the power -gamma.  K is computed on the host with its
derivatives (``gtr_consts``): with L = ln alpha^2 <= 0, s = gamma - 1 and E(x) = expm1(x) / x
(E(0) = 1),

    K = s (alpha^2 - 1) / (pi alpha^2 (alpha^(2 s) - 1)) = E(L) / (pi alpha^2 E(s L)),

finite at alpha = 1 (K = 1/pi, D uniform) and as gamma -> 1 (K -> E(L) / (pi alpha^2)); at gamma = 2,
E(s L) = E(L) and K = 1 / (pi alpha^2) exactly, GGX's D(0).
"""
from __future__ import annotations

import numpy as np

from brdfcl.model.terms.base import Param, Term, register
from brdfcl.model.terms.ndf.ggx import ALPHA

GAMMA = Param("gamma", 1.05, 4.0, 2.0, search=(1.1, 3.5),
              doc="GTR tail exponent: 2 is GGX, smaller a heavier tail (D(90) / D(0) = alpha^(2 gamma))")

_SMALL = 1e-2      # below this |x|, E and its logarithmic derivative from their series


def expm1_over_x(x):
    """E(x) = expm1(x) / x, E(0) = 1, float64, any real x (no cancellation: expm1 is exact near 0)."""
    x = np.asarray(x, dtype=np.float64)
    safe = np.where(x == 0.0, 1.0, x)
    return np.where(x == 0.0, 1.0, np.expm1(safe) / safe)


def dlog_expm1_over_x(x):
    """d ln E(x) / dx = 1 / (1 - e^-x) - 1/x; its series 1/2 + x/12 - x^3/720 near 0."""
    x = np.asarray(x, dtype=np.float64)
    small = np.abs(x) < _SMALL
    safe = np.where(small, 1.0, x)
    series = 0.5 + x / 12.0 - x ** 3 / 720.0
    return np.where(small, series, -1.0 / np.expm1(-safe) - 1.0 / safe)


def gtr_consts(alpha, gamma):
    """({'K': K}, {'K': {'alpha': dK/dalpha, 'gamma': dK/dgamma}}), float64.

    ln K = ln E(L) - ln E(s L) - ln pi - L with L = 2 ln alpha, so with psi = d ln E / dx
    d ln K / d alpha = (2 / alpha)(psi(L) - s psi(s L) - 1) and d ln K / d gamma = -L psi(s L)."""
    alpha, gamma = np.asarray(alpha, dtype=np.float64), np.asarray(gamma, dtype=np.float64)
    L = 2.0 * np.log(alpha)
    s = gamma - 1.0
    K = expm1_over_x(L) / (np.pi * alpha * alpha * expm1_over_x(s * L))
    psi_s = dlog_expm1_over_x(s * L)
    dK_da = K * (2.0 / alpha) * (dlog_expm1_over_x(L) - s * psi_s - 1.0)
    dK_dg = -K * L * psi_s
    return {"K": K}, {"K": {"alpha": dK_da, "gamma": dK_dg}}


def gtr(alpha, gamma, K):
    from sympy import exp, log

    from brdfcl.model.terms.symbols import ch, log1p, t2
    return K * exp(-gamma * (2 * log(ch) + log1p(t2 / alpha**2)))


register(Term("ndf", "gtr", (ALPHA, GAMMA), gtr, host=("K",), host_consts=gtr_consts,
              doc="generalised Trowbridge-Reitz (gamma = 2: GGX)",
              cite="Burley 2012, Physically-based shading at Disney, eq. 4 and appendix B.2"))
