"""Gaussian PSD S(f) = exp(-f^2/a^2), for comparison."""
from brdfcl.model.terms.base import Term, register
from brdfcl.model.terms.psd.hp import A


def gauss(a):
    from sympy import exp

    from brdfcl.model.terms.symbols import f
    return exp(-((f / a) ** 2))


register(Term("psd", "gauss", (A,), gauss, doc="Gaussian, for comparison"))
