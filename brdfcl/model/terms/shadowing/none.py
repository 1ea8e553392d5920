"""No shadowing: G = 1."""
from brdfcl.model.terms.base import Term, register


def one():
    from sympy import Integer
    return Integer(1)


register(Term("shadowing", "none", (), one, family="none", doc="G = 1"))
