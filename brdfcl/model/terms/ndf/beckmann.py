"""Beckmann: D = exp(-tan^2 th / alpha^2) / (pi alpha^2 cos^4 th) (Walter et al. 2007, eq. 25)."""
from brdfcl.model.terms.base import Term, register
from brdfcl.model.terms.ndf.ggx import ALPHA


def beckmann(alpha):
    from sympy import exp, pi

    from brdfcl.model.terms.symbols import ch, t2
    return exp(-t2 / alpha**2) / (pi * alpha**2 * ch**4)


register(Term("ndf", "beckmann", (ALPHA,), beckmann, doc="Beckmann", cite="Walter et al. 2007, eq. 25",
              sampled_as="beckmann"))
