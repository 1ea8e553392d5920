"""Exact unpolarised Fresnel reflectance of a conductor, eta + i k per channel, in the a^2 + b^2
form (Pharr, Jakob, Humphreys, Physically Based Rendering, 3rd ed., sec. 8.2.1):
t0 = eta^2 - k^2 - sin^2 td, S = sqrt(t0^2 + 4 eta^2 k^2) (= a^2 + b^2), a^2 = (S + t0) / 2,
Rs = (S + c^2 - 2 a c) / (S + c^2 + 2 a c), Rp = Rs Q, Q = (c^2 S + s^4 - 2 a c s^2) / (c^2 S + s^4 + 2 a c s^2).
a^2 is written 2 eta^2 k^2 / (S - t0) where t0 < 0, which is the same number without cancellation."""
from brdfcl.model.terms.base import Param, Term, register


def conductor(eta, k):
    from sympy import Piecewise, Rational, sqrt

    from brdfcl.model.terms.symbols import cd
    c2 = cd**2
    s2 = 1 - c2
    t0 = eta**2 - k**2 - s2
    S = sqrt(t0**2 + 4 * eta**2 * k**2)
    a = sqrt(Piecewise((2 * eta**2 * k**2 / (S - t0), t0 < 0), ((S + t0) / 2, True)))
    n, m = S + c2, 2 * a * cd
    u, v = c2 * S + s2**2, 2 * a * cd * s2
    Rs = (n - m) / (n + m)
    return Rational(1, 2) * Rs * (1 + (u - v) / (u + v))


register(Term("fresnel", "conductor",
              (Param("eta", 0.05, 5.0, 1.0, per_channel=True, doc="real part of the complex index"),
               Param("k", 0.05, 10.0, 3.0, per_channel=True, doc="extinction coefficient")),
              conductor, per_channel=True, doc="exact conductor, eta and k per channel",
              cite="Pharr, Jakob, Humphreys, Physically Based Rendering, 3rd ed., sec. 8.2.1"))
