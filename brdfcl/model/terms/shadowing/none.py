"""No shadowing: G = 1."""
from sympy import Integer

from brdfcl.model.terms.base import Term, register

register(Term("shadowing", "none", (), lambda: Integer(1), family="none", doc="G = 1"))
