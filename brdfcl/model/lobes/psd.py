"""Power spectral densities S(f) of the surface height (f in 1/um), normalised to S(0) = 1."""
from __future__ import annotations

import numpy as np

from brdfcl.model.lobes.spec import Param, Term, register

A = Param("a", 0.1, 1e2, 1.0, log=True, unit="1/um", search=(0.1, 20.0),
          doc="PSD corner frequency (width of the diffraction lobe); the lower bound keeps the lobe "
              "off the specular peak (half width >= ~1.5 deg at 0.526 um), the talk's separation")


def hp(f, a):
    x = (f / a) ** 2
    u = 1.0 + x
    S = 1.0 / (u * u)
    return S, {"a": 4.0 * S * x / (a * u)}


def abc(f, a, c):
    x = (f / a) ** 2
    lu = np.log1p(x)
    S = np.exp(-(c + 1.0) / 2.0 * lu)
    return S, {"a": S * (c + 1.0) * x / (a * (1.0 + x)), "c": -0.5 * lu * S}


def gauss(f, a):
    x = (f / a) ** 2
    S = np.exp(-x)
    return S, {"a": 2.0 * S * x / a}


register(Term("psd", "hp", (A,), "psd/hp.cl", "psd_hp", hp,
              cite="Holzschuch & Pacanowski, Identifying diffraction effects in measured BRDFs",
              doc="1 / (1 + f^2/a^2)^2: Fourier spectrum ~ 1/(1 + w^2), a C0 surface"))
register(Term("psd", "abc", (A, Param("c", 0.5, 8.0, 3.0, doc="ABC / K-correlation falloff exponent")),
              "psd/abc.cl", "psd_abc", abc,
              cite="Church & Takacs 1991; Low et al. 2012", doc="K-correlation, hp is c = 3"))
register(Term("psd", "gauss", (A,), "psd/gauss.cl", "psd_gauss", gauss,
              doc="Gaussian, for comparison"))
