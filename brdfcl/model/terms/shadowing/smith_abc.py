"""Smith shadowing-masking for the ABC distribution (ndf/abc.py), from its exact Lambda as a short
series (shadowing/smith.py, ``SeriesLambda``: a Chebyshev series in cos theta whose coefficients the
host computes per evaluation from the exact Smith integral, ``density_integrand``).

The rule reads D = N (1 + B (1 - cos theta_m))^-C at its nodes, beyond the slope 1/tan theta_o;
1 - cos theta_m = (1 - cos^2) / (1 + cos), without cancellation.  N (ndf/abc.py) is formed here from
B and C, as a parameter-only expression: with l = ln(1 + B), Y = 1 + B,

    1/N = (2 pi / B^2) (Y g(1 - C) - g(2 - C)),   g(k) = expm1(k l) / k,

g from its series l (1 + k l / 2 + (k l)^2 / 6) where |k| < 1e-6, so C = 1 and C = 2 (the closed
form's removable singularities) are exact.  The error against the exact Lambda (the hemisphere
integral of D's own reference) is measured by bench/lambda_gtr.py (bench/results/lambda_gtr.md) over
B in [0.1, 1e8], C in [0.25, 8].
(Heitz 2014, Understanding the masking-shadowing function, eq. 17 and 72 / 99; Low et al. 2012,
section 5, for the distribution.)
"""
from brdfcl.model.terms.shadowing.smith import CITE, SeriesLambda, density_integrand, register_series

_SERIES_BELOW = 1e-6


def _g(k, ell):
    """expm1(k l) / k, continuous through k = 0 (|k| as k^2: GLSL has no fabs)."""
    from sympy import Piecewise

    from brdfcl.model.terms.symbols import expm1
    return Piecewise((ell * (1 + k * ell / 2 + (k * ell) ** 2 / 6), k**2 < _SERIES_BELOW**2),
                     (expm1(k * ell) / k, True))


def abc_integrand(u, B, C):
    """The integrand of ABC's Lambda at one node of the density form's rule (u = tan^2 theta cos^2 b)."""
    from sympy import exp, log, pi, sqrt

    from brdfcl.model.terms.symbols import log1p
    ell = log1p(B)
    N = B**2 / (2 * pi * ((1 + B) * _g(1 - C, ell) - _g(2 - C, ell)))

    def density(q, r):                               # D at cos^2 theta_m = q, r = 1 - q
        return N * exp(-C * log(1 + B * r / (1 + sqrt(q))))

    return density_integrand(u, density)


def _no_base(d, B, C):
    """ABC's series corrects nothing: the whole Lambda is the rule's."""
    from sympy import Integer
    return Integer(0)


LAMBDA_ABC = SeriesLambda("smith_abc", ("B", "C"), _no_base, abc_integrand, __name__)
CITE_ABC = CITE + "; Low et al. 2012 (ABC)"
register_series(LAMBDA_ABC, "abc", CITE_ABC)
