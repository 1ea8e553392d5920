"""Microfacet normal distributions D (normalised: integral of D cos th over the hemisphere is 1).

Each returns (D, {param: dD/dparam}) in float64; the kernels in kernels/ndf/
compute the same.
"""
from __future__ import annotations

import numpy as np
from scipy.special import gammaln, psi

from brdfcl.model.lobes.spec import Param, Term, register

ALPHA = Param("alpha", 1e-4, 1.0, 0.1, log=True, unit="", search=(1e-3, 1.0),
              doc="roughness (slope scale); 1e-4 is a mirror at MERL's resolution")


def ggx(c, alpha):
    a2 = alpha * alpha
    s = a2 + c.t2
    D = a2 / (np.pi * c.ch ** 4 * s * s)
    return D, {"alpha": D * (2.0 / alpha - 4.0 * alpha / s)}


def beckmann(c, alpha):
    a2 = alpha * alpha
    e = c.t2 / a2
    D = np.exp(-e) / (np.pi * a2 * c.ch ** 4)
    return D, {"alpha": D * (2.0 * e - 2.0) / alpha}


# Shifted gamma distribution.  Normalisation: N = 1 / (pi I) with
# I(alpha, p) = int_0^inf exp(-(alpha^2 + x)/alpha) (alpha^2 + x)^-p dx
#             = alpha^(1-p) Gamma(1-p, alpha).
# Gamma(s, x) and dGamma/ds are integrated on t = x e^v with Gauss-Legendre
# nodes (the integrand is smooth in v and the upper tail is cut where
# exp(-t) < 1e-26); dGamma/dx = -x^(s-1) e^-x is exact.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(160)


def _upper_gamma(s, x):
    """Gamma(s, x) and dGamma/ds for x > 0 and any real s."""
    s, x = np.broadcast_arrays(np.asarray(s, float), np.asarray(x, float))
    V = np.maximum(np.log(60.0 / x), 0.0) + 3.0
    v = 0.5 * V[..., None] * (_GL_X + 1.0)
    w = 0.5 * V[..., None] * _GL_W
    lt = np.log(x)[..., None] + v
    f = np.exp(s[..., None] * lt - np.exp(lt))
    return np.sum(w * f, axis=-1), np.sum(w * f * lt, axis=-1)


def sgd_consts(alpha, p):
    s = 1.0 - p
    G, dG_ds = _upper_gamma(s, alpha)
    dG_dx = -alpha ** (s - 1.0) * np.exp(-alpha)
    lnI = s * np.log(alpha) + np.log(G)
    N = np.exp(-lnI) / np.pi
    dlnI_da = s / alpha + dG_dx / G
    dlnI_dp = -np.log(alpha) - dG_ds / G
    return ({"N": N}, {"N": {"alpha": -N * dlnI_da, "p": -N * dlnI_dp}})


def sgd(c, alpha, p, N, dN_alpha, dN_p):
    z = alpha * alpha + c.t2
    lz = np.log(z)
    h = np.exp(-z / alpha - p * lz) / c.ch ** 4
    return N * h, {"alpha": h * (dN_alpha + N * (z / alpha ** 2 - 2.0 - 2.0 * p * alpha / z)),
                   "p": h * (dN_p - N * lz)}


def epd_consts(beta, p):
    N = p / (np.pi * beta * beta * np.exp(gammaln(1.0 / p)))
    return ({"N": N}, {"N": {"beta": -2.0 * N / beta, "p": N * (1.0 / p + psi(1.0 / p) / p ** 2)}})


def epd(c, beta, p, N, dN_beta, dN_p):
    lt = np.log(c.t2 / (beta * beta))
    q = np.exp(np.minimum(p * lt, 80.0))
    h = np.exp(-q) / c.ch ** 4
    hq = h * q
    return N * h, {"beta": h * dN_beta + hq * (N * 2.0 * p / beta),
                   "p": h * dN_p - hq * lt * N}


def _consts_adapter(fn):
    """Host constants in the Term protocol: ({'N': v, 'dN_<param>': d}, ...) flattened."""
    def consts(**params):
        k, d = fn(**params)
        out = {"N": k["N"]}
        for name, v in d["N"].items():
            out[f"dN_{name}"] = v
        return out
    return consts


register(Term("ndf", "ggx", (ALPHA,), "ndf/ggx.cl", "ndf_ggx", ggx,
              cite="Walter et al. 2007, Microfacet models for refraction, eq. 33",
              doc="GGX / Trowbridge-Reitz"))
register(Term("ndf", "beckmann", (ALPHA,), "ndf/beckmann.cl", "ndf_beckmann", beckmann,
              cite="Walter et al. 2007, eq. 25", doc="Beckmann"))
register(Term("ndf", "sgd",
              (Param("alpha", 1e-4, 2.0, 0.1, log=True, doc="SGD scale"),
               Param("p", 0.05, 2.0, 0.8, doc="SGD shape (heavier tails as p grows)")),
              "ndf/sgd.cl", "ndf_sgd", sgd,
              cite="Bagher, Soler, Holzschuch 2012, Accurate fitting of measured reflectances "
                   "using a shifted gamma micro-facet distribution, eq. 6",
              consts=_consts_adapter(sgd_consts), const_names=("N", "dN_alpha", "dN_p"),
              doc="shifted gamma distribution"))
register(Term("ndf", "epd",
              (Param("beta", 1e-4, 2.0, 0.1, log=True, doc="EPD slope scale"),
               Param("p", 0.1, 4.0, 1.0, doc="EPD exponent (p = 1: Beckmann)")),
              "ndf/epd.cl", "ndf_epd", epd,
              cite="Holzschuch & Pacanowski 2017, A two-scale microfacet reflectance model "
                   "combining reflection and diffraction",
              consts=_consts_adapter(epd_consts), const_names=("N", "dN_beta", "dN_p"),
              doc="exponential power distribution"))
