"""GGX / Trowbridge-Reitz: D = alpha^2 / (pi cos^4 th (alpha^2 + tan^2 th)^2)
(Walter et al. 2007, Microfacet models for refraction, eq. 33)."""
from brdfcl.model.terms.base import Param, Term, register

ALPHA = Param("alpha", 1e-4, 1.0, 0.1, log=True, unit="", search=(1e-3, 1.0),
              doc="roughness (slope scale); 1e-4 is a mirror at MERL's resolution")


def ggx(alpha):
    from sympy import pi

    from brdfcl.model.terms.symbols import ch, t2
    return alpha**2 / (pi * ch**4 * (alpha**2 + t2) ** 2)


register(Term("ndf", "ggx", (ALPHA,), ggx, doc="GGX / Trowbridge-Reitz", sampled_as="ggx",
              cite="Walter et al. 2007, Microfacet models for refraction, eq. 33"))
