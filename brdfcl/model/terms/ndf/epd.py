"""Exponential power distribution (Holzschuch & Pacanowski 2017):
D = N exp(-(tan^2 th / beta^2)^p) / cos^4 th, N = p / (pi beta^2 Gamma(1/p)) (host side)."""
from __future__ import annotations

import numpy as np

from brdfcl.model.terms.base import Param, Term, register


def epd_consts(beta, p):
    """({'N': N}, {'N': {'beta': dN/dbeta, 'p': dN/dp}})."""
    from scipy.special import gammaln, psi  # here: importing scipy.special costs every start-up 0.1 s
    N = p / (np.pi * beta * beta * np.exp(gammaln(1.0 / p)))
    return ({"N": N}, {"N": {"beta": -2.0 * N / beta, "p": N * (1.0 / p + psi(1.0 / p) / p ** 2)}})


def epd(beta, p, N):
    from sympy import exp, log

    from brdfcl.model.terms.symbols import ch, exp_clamped, t2
    q = exp_clamped(p * log(t2 / beta**2))      # (tan^2 th / beta^2)^p without overflow
    return N * exp(-q) / ch**4


register(Term("ndf", "epd",
              (Param("beta", 1e-4, 2.0, 0.1, log=True, doc="EPD slope scale"),
               Param("p", 0.1, 4.0, 1.0, doc="EPD exponent (p = 1: Beckmann)")),
              epd, host=("N",), host_consts=epd_consts, doc="exponential power distribution",
              cite="Holzschuch & Pacanowski 2017, A two-scale microfacet reflectance model "
                   "combining reflection and diffraction"))
