"""No Fresnel factor: F = 1 (the lobe's amplitude carries the reflectance)."""
from sympy import Integer

from brdfcl.model.terms.base import Term, register

register(Term("fresnel", "none", (), lambda: Integer(1), doc="F = 1"))
