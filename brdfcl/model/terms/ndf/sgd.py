"""Shifted gamma distribution (Bagher, Soler, Holzschuch 2012, eq. 6):
D = N(alpha, p) exp(-(alpha^2 + tan^2 th) / alpha) (alpha^2 + tan^2 th)^-p / cos^4 th.

N = 1 / (pi I) normalises D cos th over the hemisphere, with
I(alpha, p) = int_0^inf exp(-(alpha^2 + x)/alpha) (alpha^2 + x)^-p dx = alpha^(1-p) Gamma(1-p, alpha),
computed on the host with its derivatives (``sgd_consts``).
"""
from __future__ import annotations

import numpy as np

from brdfcl.model.terms.base import Param, Term, register

# Gamma(s, x) and dGamma/ds are integrated on t = x e^v with Gauss-Legendre nodes (the integrand
# is smooth in v and the upper tail is cut where exp(-t) < 1e-26); dGamma/dx = -x^(s-1) e^-x.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(160)


def upper_gamma(s, x):
    """Gamma(s, x) and dGamma/ds for x > 0 and any real s."""
    s, x = np.broadcast_arrays(np.asarray(s, float), np.asarray(x, float))
    V = np.maximum(np.log(60.0 / x), 0.0) + 3.0
    v = 0.5 * V[..., None] * (_GL_X + 1.0)
    w = 0.5 * V[..., None] * _GL_W
    lt = np.log(x)[..., None] + v
    g = np.exp(s[..., None] * lt - np.exp(lt))
    return np.sum(w * g, axis=-1), np.sum(w * g * lt, axis=-1)


def sgd_consts(alpha, p):
    """({'N': N}, {'N': {'alpha': dN/dalpha, 'p': dN/dp}})."""
    s = 1.0 - p
    G, dG_ds = upper_gamma(s, alpha)
    dG_dx = -alpha ** (s - 1.0) * np.exp(-alpha)
    lnI = s * np.log(alpha) + np.log(G)
    N = np.exp(-lnI) / np.pi
    dlnI_da = s / alpha + dG_dx / G
    dlnI_dp = -np.log(alpha) - dG_ds / G
    return ({"N": N}, {"N": {"alpha": -N * dlnI_da, "p": -N * dlnI_dp}})


def sgd(alpha, p, N):
    from sympy import exp, log

    from brdfcl.model.terms.symbols import ch, t2
    z = alpha**2 + t2
    return N * exp(-z / alpha - p * log(z)) / ch**4


register(Term("ndf", "sgd",
              (Param("alpha", 1e-4, 2.0, 0.1, log=True, doc="SGD scale"),
               Param("p", 0.05, 2.0, 0.8, doc="SGD shape (heavier tails as p grows)")),
              sgd, host=("N",), host_consts=sgd_consts, doc="shifted gamma distribution",
              cite="Bagher, Soler, Holzschuch 2012, Accurate fitting of measured reflectances "
                   "using a shifted gamma micro-facet distribution, eq. 6"))
