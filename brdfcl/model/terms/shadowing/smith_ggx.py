"""Smith shadowing-masking for GGX (Walter et al. 2007, eq. 34):
Lambda = (sqrt(1 + alpha^2 tan^2) - 1) / 2, written without cancellation."""
from brdfcl.model.terms.base import Term, register
from brdfcl.model.terms.shadowing.smith import CITE, correlated, separable


def lambda_ggx(d, alpha):
    from sympy import sqrt
    u = alpha**2 * d.tan2
    return u / (2 * (1 + sqrt(1 + u)))


register(Term("shadowing", "smith_ggx", (), separable(lambda_ggx), uses=("alpha",), ndfs=("ggx",), family="smith",
              cite=CITE, doc="separable Smith for GGX"))
register(Term("shadowing", "smith_ggx_hc", (), correlated(lambda_ggx), uses=("alpha",), ndfs=("ggx",),
              family="smith-hc", cite=CITE, doc="height-correlated Smith for GGX"))
