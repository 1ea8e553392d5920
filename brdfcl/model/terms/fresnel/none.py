"""No Fresnel factor: F = 1 (the lobe's amplitude carries the reflectance)."""
from brdfcl.model.terms.base import Term, register


def one():
    from sympy import Integer
    return Integer(1)


register(Term("fresnel", "none", (), one, doc="F = 1"))
