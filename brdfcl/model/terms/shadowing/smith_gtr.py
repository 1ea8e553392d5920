"""Smith shadowing-masking for GTR (ndf/gtr.py), from its exact Lambda evaluated by a fixed rule.

GTR's Lambda has no closed form for gamma != 2 (its slope distribution is not shape-invariant), so
the exact Smith integral of shadowing/smith.py (``lambda_from_density``) is evaluated by an
N_NODES-point Gauss-Legendre rule, with GGX's closed form as a control variate:

    Lambda_gtr = Lambda_ggx(alpha) + rule[D_gtr - D_ggx],

so that gamma = 2 is GGX's Smith G exactly, and alpha = 1 too (D uniform, GGX's, for any gamma).
At a node, with q = cos^2 theta_m, 1 - q = r and rest = r + alpha^2 q = cos^2 (1 + tan^2 / alpha^2)
alpha^2, D_gtr = c rest^-gamma and D_ggx = alpha^2 / (pi rest^2), where c = (gamma - 1)(1 - alpha^2) /
(pi (alpha^(2 - 2 gamma) - 1)) (Burley 2012, eq. 4 and appendix B.2) is formed here as a
parameter-only expression, s k / (pi expm1(-2 s ln alpha)) with s = gamma - 1, k = (1 - alpha)
(1 + alpha): no cancellation anywhere (rest is a sum of positive terms, expm1 is exact near 0).  Each
node costs one log and one exp; the derivatives reuse them.

The rule's error is measured against the exact Lambda (the hemisphere integral of D's own
reference) by bench/lambda_gtr.py (bench/results/lambda_gtr.md): the largest relative error of
G1 = 1/(1 + Lambda) for theta_o <= 80 deg is 2.9e-4 over the whole box (alpha 1e-4..1, gamma
1.05..4; at alpha = 0.68, gamma = 4, 80 deg) and 3.8e-5 in the region fits use (alpha 0.005..0.3,
gamma 1.1..3).  In that region GGX's Lambda with the same alpha is off by up to 53%, and with an
alpha matched to Lambda at small theta_o by up to 10%.  (Heitz 2014, Understanding the
masking-shadowing function, eq. 17 for Lambda and 72 / 99 for G.)
"""
from sympy import Piecewise, exp, log, pi

from brdfcl.model.terms.base import Term, register
from brdfcl.model.terms.shadowing.smith import CITE, correlated, expm1, lambda_from_density, separable
from brdfcl.model.terms.shadowing.smith_ggx import lambda_ggx

N_NODES = 10


def lambda_gtr(tan2, alpha, gamma, n=N_NODES):
    s = gamma - 1
    a2 = alpha**2
    # at alpha = 1 (D uniform, = GGX's for any gamma) the correction is 0 and c's 0/0 is not formed:
    # two parameter-only switches (scalar ternaries in the kernels)
    on = Piecewise((0, alpha >= 1), (1, True))
    c = Piecewise((1 / pi, alpha >= 1),
                  (s * (1 - alpha) * (1 + alpha) / (pi * expm1(-2 * s * log(alpha))), True))

    def density(q, r):                               # D_gtr - D_ggx at cos^2 theta_m = q
        rest = r + a2 * q
        return c * exp(-gamma * log(rest)) - a2 / (pi * rest**2)

    return lambda_ggx(tan2, alpha) + on * lambda_from_density(tan2, density, n)


CITE_GTR = CITE + "; Burley 2012 (GTR)"
register(Term("shadowing", "smith_gtr", (), separable(lambda_gtr), uses=("alpha", "gamma"), ndfs=("gtr",),
              cite=CITE_GTR, doc=f"separable Smith for GTR, exact Lambda by a {N_NODES}-node rule"))
register(Term("shadowing", "smith_gtr_hc", (), correlated(lambda_gtr), uses=("alpha", "gamma"), ndfs=("gtr",),
              cite=CITE_GTR, doc=f"height-correlated Smith for GTR, exact Lambda by a {N_NODES}-node rule"))
