"""Smith shadowing-masking for the ABC distribution (ndf/abc.py), from its exact Lambda evaluated by
a fixed rule (shadowing/smith.py, ``lambda_from_density``).

The rule reads D = N (1 + B (1 - cos theta_m))^-C at its nodes, beyond the slope 1/tan theta_o;
1 - cos theta_m = (1 - cos^2) / (1 + cos), without cancellation.  N (ndf/abc.py) is formed here from
B and C, as a parameter-only expression: with l = ln(1 + B), Y = 1 + B,

    1/N = (2 pi / B^2) (Y g(1 - C) - g(2 - C)),   g(k) = expm1(k l) / k,

g from its series l (1 + k l / 2 + (k l)^2 / 6) where |k| < 1e-6, so C = 1 and C = 2 (the closed
form's removable singularities) are exact.  The rule's error is measured against the exact Lambda
(the hemisphere integral of D's own reference) by bench/lambda_gtr.py (bench/results/lambda_gtr.md):
with N_NODES = 12 the largest relative error of G1 = 1/(1 + Lambda) for theta_o <= 80 deg is 2.3e-4
over B in [0.1, 1e8], C in [0.25, 8] (for the roughest lobes, B < 1, at 80 deg) and 9.7e-5 where the
published fits lie (B 10..1e5, C 0.5..6).
(Heitz 2014, Understanding the masking-shadowing function, eq. 17 and 72 / 99; Low et al. 2012,
section 5, for the distribution.)
"""
from sympy import Piecewise, exp, log, pi, sqrt

from brdfcl.model.terms.base import Term, register
from brdfcl.model.terms.shadowing.smith import CITE, correlated, expm1, lambda_from_density, separable
from brdfcl.model.terms.symbols import log1p

N_NODES = 12
_SERIES_BELOW = 1e-6


def _g(k, ell):
    """expm1(k l) / k, continuous through k = 0 (|k| as k^2: GLSL has no fabs)."""
    return Piecewise((ell * (1 + k * ell / 2 + (k * ell) ** 2 / 6), k**2 < _SERIES_BELOW**2),
                     (expm1(k * ell) / k, True))


def lambda_abc(tan2, B, C, n=N_NODES):
    ell = log1p(B)
    N = B**2 / (2 * pi * ((1 + B) * _g(1 - C, ell) - _g(2 - C, ell)))

    def density(q, r):                               # D at cos^2 theta_m = q, r = 1 - q
        return N * exp(-C * log(1 + B * r / (1 + sqrt(q))))

    return lambda_from_density(tan2, density, n)


CITE_ABC = CITE + "; Low et al. 2012 (ABC)"
register(Term("shadowing", "smith_abc", (), separable(lambda_abc), uses=("B", "C"), ndfs=("abc",),
              cite=CITE_ABC, doc=f"separable Smith for ABC, exact Lambda by a {N_NODES}-node rule"))
register(Term("shadowing", "smith_abc_hc", (), correlated(lambda_abc), uses=("B", "C"), ndfs=("abc",),
              cite=CITE_ABC, doc=f"height-correlated Smith for ABC, exact Lambda by a {N_NODES}-node rule"))
