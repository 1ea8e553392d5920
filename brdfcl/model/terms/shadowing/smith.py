"""Smith shadowing-masking from a distribution's Lambda (Heitz 2014, Understanding the
masking-shadowing function, eq. 72 (separable) and 99 (height-correlated))."""
from __future__ import annotations

from brdfcl.model.terms.symbols import t2i, t2o

CITE = "Walter et al. 2007; Heitz 2014, Understanding the masking-shadowing function"


def separable(lam):
    """G = G1(i) G1(o), G1 = 1 / (1 + Lambda(tan^2 theta))."""
    return lambda alpha: 1 / ((1 + lam(t2i, alpha)) * (1 + lam(t2o, alpha)))


def correlated(lam):
    """G = 1 / (1 + Lambda(i) + Lambda(o))."""
    return lambda alpha: 1 / (1 + lam(t2i, alpha) + lam(t2o, alpha))
