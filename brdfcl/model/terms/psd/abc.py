"""ABC / K-correlation PSD (Church & Takacs 1991; Low et al. 2012), B folded into a:
S(f) = (1 + f^2/a^2)^(-(c+1)/2); hp is c = 3."""
from brdfcl.model.terms.base import Param, Term, register
from brdfcl.model.terms.psd.hp import A


def abc(a, c):
    from sympy import exp

    from brdfcl.model.terms.symbols import f, log1p
    return exp(-(c + 1) / 2 * log1p((f / a) ** 2))


register(Term("psd", "abc", (A, Param("c", 0.5, 8.0, 3.0, doc="ABC / K-correlation falloff exponent")),
              abc, cite="Church & Takacs 1991; Low et al. 2012", doc="K-correlation, hp is c = 3"))
