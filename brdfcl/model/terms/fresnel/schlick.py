"""Schlick's approximation: F = F0 + (1 - F0) (1 - cos td)^5, F0 per channel
(Schlick 1994, An inexpensive BRDF model for physically-based rendering)."""
from brdfcl.model.terms.base import Param, Term, register


def schlick(F0):
    from brdfcl.model.terms.symbols import s5
    return F0 + (1 - F0) * s5


register(Term("fresnel", "schlick",
              (Param("F0", 0.0, 1.0, 0.5, per_channel=True, doc="reflectance at normal incidence"),),
              schlick, per_channel=True, doc="Schlick's approximation, F0 per channel",
              cite="Schlick 1994, An inexpensive BRDF model for physically-based rendering"))
