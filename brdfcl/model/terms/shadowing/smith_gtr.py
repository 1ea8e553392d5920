"""Smith shadowing-masking for GTR (ndf/gtr.py), from its exact Lambda as a short series.

GTR's Lambda has no closed form for gamma != 2 (its slope distribution is not shape-invariant).  It is
written as GGX's closed form with the same alpha plus a correction, Lambda_gtr = Lambda_ggx(alpha) +
rule[D_gtr - D_ggx], the exact Smith integral of shadowing/smith.py (``density_integrand``) of the
difference of the two distributions, so that gamma = 2 is GGX's Smith G exactly, and alpha = 1 too
(D uniform, GGX's, for any gamma).  The kernels read the correction as a Chebyshev series in
cos theta whose coefficients the host computes per evaluation from the rule (shadowing/smith.py,
``SeriesLambda``).

At a node of the rule, with q = cos^2 theta_m, 1 - q = r and rest = r + alpha^2 q = cos^2 (1 + tan^2 /
alpha^2) alpha^2, D_gtr = c rest^-gamma and D_ggx = alpha^2 / (pi rest^2), where c = (gamma - 1)(1 -
alpha^2) / (pi (alpha^(2 - 2 gamma) - 1)) (Burley 2012, eq. 4 and appendix B.2) is formed as
s k / (pi expm1(-2 s ln alpha)) with s = gamma - 1, k = (1 - alpha)(1 + alpha): no cancellation
anywhere (rest is a sum of positive terms, expm1 is exact near 0).

The error against the exact Lambda (the hemisphere integral of D's own reference) is measured by
bench/lambda_gtr.py (bench/results/lambda_gtr.md), over the whole box alpha 1e-4..1, gamma 1.05..4.
(Heitz 2014, Understanding the masking-shadowing function, eq. 17 for Lambda and 72 / 99 for G.)
"""
from brdfcl.model.terms.shadowing.series_table import Box
from brdfcl.model.terms.shadowing.smith import CITE, SeriesLambda, density_integrand, register_series
from brdfcl.model.terms.shadowing.smith_ggx import lambda_ggx


def gtr_integrand(u, alpha, gamma):
    """The integrand of Lambda_gtr - Lambda_ggx at one node of the density form's rule (u = tan^2
    theta cos^2 b)."""
    from sympy import Piecewise, exp, log, pi

    from brdfcl.model.terms.symbols import expm1
    s = gamma - 1
    a2 = alpha**2
    # at alpha = 1 (D uniform, = GGX's for any gamma) the correction is 0 and c's 0/0 is not formed:
    # two parameter-only switches
    on = Piecewise((0, alpha >= 1), (1, True))
    c = Piecewise((1 / pi, alpha >= 1),
                  (s * (1 - alpha) * (1 + alpha) / (pi * expm1(-2 * s * log(alpha))), True))

    def density(q, r):                               # D_gtr - D_ggx at cos^2 theta_m = q
        rest = r + a2 * q
        return c * exp(-gamma * log(rest)) - a2 / (pi * rest**2)

    return on * density_integrand(u, density)


TABLE_BOX = Box(lo=(1e-4, 1.05), hi=(0.9, 4.0), log=(True, False), nodes=(128, 60))
"""Where the coefficients are tabulated (series_table): GTR's box but alpha above 0.9, where they
change too fast near alpha = 1 for the grid (the rule serves there); gamma every 0.05, so that
gamma = 2 (GGX, correction 0) is a node line."""
LAMBDA_GTR = SeriesLambda("smith_gtr", ("alpha", "gamma"), lambda d, alpha, gamma: lambda_ggx(d, alpha),
                          gtr_integrand, __name__, box=TABLE_BOX)
CITE_GTR = CITE + "; Burley 2012 (GTR)"
register_series(LAMBDA_GTR, "gtr", CITE_GTR)
