"""Exact unpolarised Fresnel reflectance of a dielectric (Walter et al. 2007, eq. 22):
g = sqrt(eta^2 - 1 + c^2), c = cos td, F = A^2 (1 + B^2) / 2,
A = (g - c) / (g + c), B = (c (g + c) - 1) / (c (g - c) + 1)."""
from brdfcl.model.terms.base import Param, Term, register


def dielectric(eta):
    from sympy import Rational, sqrt

    from brdfcl.model.terms.symbols import cd
    g = sqrt(eta**2 - 1 + cd**2)
    A = (g - cd) / (g + cd)
    B = (cd * (g + cd) - 1) / (cd * (g - cd) + 1)
    return Rational(1, 2) * A**2 * (1 + B**2)


register(Term("fresnel", "dielectric", (Param("eta", 1.01, 3.0, 1.5, doc="relative index of refraction"),),
              dielectric, cite="Walter et al. 2007, eq. 22", doc="exact dielectric, one eta"))
