"""Shadowing-masking G terms.  Smith forms read the alpha of their D."""
from __future__ import annotations

import numpy as np
from scipy.special import erfc

from brdfcl.model.lobes.spec import Term, register


def _lambda_ggx(t2, alpha):
    u = alpha * alpha * t2
    r = np.sqrt(1.0 + u)
    return u / (2.0 * (1.0 + r)), alpha * t2 / (2.0 * r)


def _lambda_beckmann(t2, alpha):
    with np.errstate(divide="ignore", invalid="ignore"):
        a = 1.0 / (alpha * np.sqrt(t2))
        e = np.exp(-a * a) / (a * np.sqrt(np.pi))
    e = np.where(np.isfinite(a), e, 0.0)
    return (e - erfc(a)) / 2.0, e / (2.0 * alpha)


def _separable(lam):
    def G(c, alpha):
        li, di = lam(c.t2i, alpha)
        lo, dl = lam(c.t2o, alpha)
        g = 1.0 / ((1.0 + li) * (1.0 + lo))
        return g, {"alpha": -g * (di / (1.0 + li) + dl / (1.0 + lo))}
    return G


def _correlated(lam):
    def G(c, alpha):
        li, di = lam(c.t2i, alpha)
        lo, dl = lam(c.t2o, alpha)
        g = 1.0 / (1.0 + li + lo)
        return g, {"alpha": -g * g * (di + dl)}
    return G


def vcavity(c):
    return c.gv, {}


def none(c):
    return np.ones_like(c.ch), {}


_SMITH = "Walter et al. 2007; Heitz 2014, Understanding the masking-shadowing function"
register(Term("shadowing", "smith_ggx", (), "shadowing/smith_ggx.cl", "g_smith_ggx",
              _separable(_lambda_ggx), uses=("alpha",), ndfs=("ggx",), cite=_SMITH,
              doc="separable Smith for GGX"))
register(Term("shadowing", "smith_ggx_hc", (), "shadowing/smith_ggx.cl", "g_smith_ggx_hc",
              _correlated(_lambda_ggx), uses=("alpha",), ndfs=("ggx",), cite=_SMITH,
              doc="height-correlated Smith for GGX"))
register(Term("shadowing", "smith_beckmann", (), "shadowing/smith_beckmann.cl", "g_smith_beckmann",
              _separable(_lambda_beckmann), uses=("alpha",), ndfs=("beckmann",), cite=_SMITH,
              doc="separable Smith for Beckmann"))
register(Term("shadowing", "smith_beckmann_hc", (), "shadowing/smith_beckmann.cl",
              "g_smith_beckmann_hc", _correlated(_lambda_beckmann), uses=("alpha",),
              ndfs=("beckmann",), cite=_SMITH, doc="height-correlated Smith for Beckmann"))
register(Term("shadowing", "vcavity", (), "shadowing/vcavity.cl", "g_vcavity", vcavity,
              cite="Cook & Torrance 1982", doc="V-cavity, any D"))
register(Term("shadowing", "none", (), "shadowing/none.cl", "g_none", none, doc="G = 1"))
