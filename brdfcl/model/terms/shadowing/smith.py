"""Smith shadowing-masking from a distribution's Lambda (Heitz 2014, Understanding the
masking-shadowing function, eq. 72 (separable) and 99 (height-correlated)).

For a distribution whose Lambda has no closed form (GTR, ABC), the exact Smith Lambda (Heitz 2014,
eq. 17 with the projected area of eq. 9: 1 + Lambda(o) = int max(0, o.m) D(m) dm / cos theta_o, so
Lambda(o) = int max(0, -o.m) D(m) dm / cos theta_o, the back-facing microfacets' projected area) is
evaluated by a fixed Gauss-Legendre rule.  With tau = tan theta_o and t = tan theta_m, the phi
integral in closed form gives (Heitz 2014, eq. 72's Lambda for an isotropic P22 = D cos^4 theta_m)

    Lambda(tau) = 2 int_{1/tau}^inf w(tau t) P22(t) t dt,   w(x) = sqrt(x^2 - 1) - arccos(1/x),

and, by parts, with P(t) the share of the projected microfacet area (D cos theta_m) beyond t,

    Lambda(tau) = (1/pi) int_{1/tau}^inf sqrt(tau^2 t^2 - 1) / t P(t) dt.

t = 1 / (tau cos b) maps both onto b in [0, pi/2) with smooth, bounded integrands:

    Lambda = (1/pi) int tan^2 b P db                                          (``lambda_from_share``)
           = 2 int (tan b - b) sin b cos b tau^2 D(theta_m) / (1 + tau^2 cos^2 b)^2 db  (``lambda_from_density``)

(P ~ 1/t^2 and D -> D(90 deg) in the tail).  They only read the distribution beyond the slope
1/tau >= cot 80 deg = 0.18, so the peak's width (alpha = 1e-4 or 1) never has to be resolved.  At the
nodes cos^2 theta_m = q = tau^2 cos^2 b / (1 + tau^2 cos^2 b).  The share form needs a closed-form
cumulative and is the more accurate for a given number of nodes; the density form needs only D.
The rules' errors (bench/lambda_gtr.py) are largest for rough lobes near theta_o = 80 deg, the
default angle cut-off of a fit; beyond it the integrands' features crowd into b -> pi/2 and a rule
underestimates Lambda: the relative error of G1 = 1/(1 + Lambda) grows to ~1e-2 at 85 deg, ~0.1 at
88 deg and ~1 at 89.5 deg (for the roughest lobes, where G1 itself is small).  GGX's
P(t) = alpha^2 / (alpha^2 + t^2) gives its closed form back, (sqrt(1 + alpha^2 tau^2) - 1) / 2.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from brdfcl.model.terms.symbols import t2i, t2o

CITE = "Walter et al. 2007; Heitz 2014, Understanding the masking-shadowing function"


def separable(lam):
    """G = G1(i) G1(o), G1 = 1 / (1 + Lambda(tan^2 theta)); ``lam(tan2, **d_params)``."""
    return lambda **p: 1 / ((1 + lam(t2i, **p)) * (1 + lam(t2o, **p)))


def correlated(lam):
    """G = 1 / (1 + Lambda(i) + Lambda(o))."""
    return lambda **p: 1 / (1 + lam(t2i, **p) + lam(t2o, **p))


class expm1(sp.Function):
    """e^z - 1, exact near 0.  Printed for the kernels (and so the GLSL export, which has no expm1)
    as 2 sinh(z/2) exp(z/2), for the float64 reference as numpy's expm1; its derivative is written
    expm1(z) + 1, so that a derivative reuses the value instead of calling another function."""

    nargs = 1

    def fdiff(self, argindex=1):
        return self + 1

    def _ccode(self, printer):
        half = self.args[0] / 2
        return f"({printer._print(2 * sp.sinh(half) * sp.exp(half))})"

    def _pythoncode(self, printer):
        return f"{printer._module_format('numpy.expm1')}({printer._print(self.args[0])})"


def _nodes(n):
    """Gauss-Legendre nodes b_j and weights w_j on [0, pi/2]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return np.pi / 4 * (x + 1.0), np.pi / 4 * w


def _rule(tan2, n, coef, f):
    """sum_j coef_j f(q_j, r_j, u_j): u_j = tan^2 theta_o cos^2 b_j, q_j = u_j / (1 + u_j) = cos^2 theta_m
    and r_j = 1 - q_j = 1 / (1 + u_j) (passed apart: no cancellation)."""
    b, _ = _nodes(n)
    out = 0
    for cj, bj in zip(coef, b):
        u = tan2 * float(np.cos(bj) ** 2)
        out = out + float(cj) * f(u / (1 + u), 1 / (1 + u), u)
    return out


def lambda_from_share(tan2, share, n):
    """Lambda(tan^2 theta_o) by the n-node rule on (1/pi) int tan^2 b P db, ``share(q, r)`` = P at
    cos^2 theta_m = q (r = 1 - q); SymPy expressions in, one out."""
    b, w = _nodes(n)
    return _rule(tan2, n, w * np.tan(b) ** 2 / np.pi, lambda q, r, u: share(q, r))


def lambda_from_density(tan2, density, n):
    """Lambda(tan^2 theta_o) by the n-node rule on 2 int (tan b - b) sin b cos b tau^2 D / (1 + u)^2 db
    (u = tau^2 cos^2 b, so cos b tau^2 / (1 + u)^2 = u r^2 / cos b), ``density(q, r)`` = D at
    cos^2 theta_m = q."""
    b, w = _nodes(n)
    return _rule(tan2, n, 2 * w * (np.tan(b) - b) * np.sin(b) / np.cos(b),
                 lambda q, r, u: u * r * r * density(q, r))
