"""Smith shadowing-masking for Beckmann (Walter et al. 2007, eq. 27):
a = 1 / (alpha tan theta), Lambda = (exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2."""
from brdfcl.model.terms.base import Term, register
from brdfcl.model.terms.shadowing.smith import CITE, correlated, separable


def lambda_beckmann(d, alpha):
    from sympy import erfc, exp, pi, sqrt
    a = 1 / (alpha * sqrt(d.tan2))
    return (exp(-a**2) / (a * sqrt(pi)) - erfc(a)) / 2


register(Term("shadowing", "smith_beckmann", (), separable(lambda_beckmann), uses=("alpha",), family="smith",
              ndfs=("beckmann",), cite=CITE, doc="separable Smith for Beckmann"))
register(Term("shadowing", "smith_beckmann_hc", (), correlated(lambda_beckmann), uses=("alpha",), family="smith-hc",
              ndfs=("beckmann",), cite=CITE, doc="height-correlated Smith for Beckmann"))
