"""Fresnel factors F(theta_d).  Per-channel terms are evaluated once per channel."""
from __future__ import annotations

import numpy as np

from brdfcl.model.lobes.spec import Param, Term, register


def none(c):
    return np.ones_like(c.cd), {}


def schlick(c, F0):
    s5 = (1.0 - c.cd) ** 5
    return F0 + (1.0 - F0) * s5, {"F0": 1.0 - s5}


def dielectric(c, eta):
    cd = c.cd
    g = np.sqrt(eta * eta - 1.0 + cd * cd)
    gp, gm = g + cd, g - cd
    A = gm / gp
    bn, bd = cd * gp - 1.0, cd * gm + 1.0
    B = bn / bd
    dA = 2.0 * cd / gp ** 2
    dB = 2.0 * cd * (1.0 - cd * cd) / bd ** 2
    F = 0.5 * A * A * (1.0 + B * B)
    return F, {"eta": (eta / g) * (A * dA * (1.0 + B * B) + A * A * B * dB)}


def conductor(c, eta, k):
    cd = c.cd
    c2 = cd * cd
    s2 = 1.0 - c2
    t0 = eta * eta - k * k - s2
    S = np.sqrt(t0 * t0 + 4.0 * eta * eta * k * k)
    with np.errstate(divide="ignore", invalid="ignore"):
        a2 = np.where(t0 < 0, 2.0 * eta * eta * k * k / (S - t0), (S + t0) / 2.0)
    a = np.sqrt(a2)
    dS = {"eta": 2.0 * eta * (t0 + 2.0 * k * k) / S, "k": 2.0 * k * (2.0 * eta * eta - t0) / S}
    da = {"eta": eta * (a2 + k * k) / (a * S), "k": k * (eta * eta - a2) / (a * S)}
    n, m = S + c2, 2.0 * a * cd
    Rs = (n - m) / (n + m)
    u, v = c2 * S + s2 * s2, 2.0 * a * cd * s2
    Q = (u - v) / (u + v)
    grads = {}
    for p in ("eta", "k"):
        dRs = 2.0 * (m * dS[p] - n * 2.0 * cd * da[p]) / (n + m) ** 2
        dQ = 2.0 * (v * c2 * dS[p] - u * 2.0 * cd * s2 * da[p]) / (u + v) ** 2
        grads[p] = 0.5 * (dRs * (1.0 + Q) + Rs * dQ)
    return 0.5 * Rs * (1.0 + Q), grads


register(Term("fresnel", "none", (), "fresnel/none.cl", "fresnel_none", none, doc="F = 1"))
register(Term("fresnel", "schlick",
              (Param("F0", 0.0, 1.0, 0.5, per_channel=True, doc="reflectance at normal incidence"),),
              "fresnel/schlick.cl", "fresnel_schlick", schlick, per_channel=True,
              cite="Schlick 1994, An inexpensive BRDF model for physically-based rendering",
              doc="Schlick's approximation, F0 per channel"))
register(Term("fresnel", "dielectric",
              (Param("eta", 1.01, 3.0, 1.5, doc="relative index of refraction"),),
              "fresnel/dielectric.cl", "fresnel_dielectric", dielectric,
              cite="Walter et al. 2007, eq. 22", doc="exact dielectric, one eta"))
register(Term("fresnel", "conductor",
              (Param("eta", 0.05, 5.0, 1.0, per_channel=True, doc="real part of the complex index"),
               Param("k", 0.05, 10.0, 3.0, per_channel=True, doc="extinction coefficient")),
              "fresnel/conductor.cl", "fresnel_conductor", conductor, per_channel=True,
              cite="Pharr, Jakob, Humphreys, Physically Based Rendering, 3rd ed., sec. 8.2.1",
              doc="exact conductor, eta and k per channel"))
