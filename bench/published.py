"""Published per-material fits of two BRDF models to the MERL materials, to compare brdfcl's fits with.

* ``sgd_bagher2012``: the Shifted Gamma Distribution microfacet model of Bagher, Soler, Holzschuch,
  "Accurate fitting of measured reflectances using a Shifted Gamma micro-facet distribution",
  Computer Graphics Forum 31(4), 2012.
* ``abc_low2012_microfacet_e2`` and ``abc_low2012_smooth_e2``: the ABC microfacet and smooth-surface
  models of Low (Löw), Kronander, Ynnerman, Unger, "BRDF models for accurate and efficient rendering of
  glossy surfaces", ACM TOG 31(1), 2012, fitted with the paper's E2 (cosine-weighted log) metric.

The numbers (``bench/published/<model>.csv``) are the fits that the BSDF benchmark BBM
(github.com/bsdfbenchmark/bbm, commit 9807fb38d7ab51802f3a0fe0f65cf763cb01a0f4, ``fits/*.fit``) collected
from the papers' published material, copied verbatim; each file's ``#`` header names its source and the
meaning of every column.  :func:`evaluate` is the model exactly as BBM evaluates these fits
(``include/bsdfmodel/bagher.h``, ``lowmicrofacet.h``, ``low.h``, ``lowsmooth.h``), which is what the
numbers were fitted with where the paper's text differs (the 1/pi of the ABC microfacet fits).  It was
checked against BBM's own C++ code (native backbone, double precision) at random direction pairs.

Scale: values are BRDFs in 1/sr on MERL's scaled RGB, the stored MERL numbers times (1/1500, 1.15/1500,
1.66/1500) for (R, G, B).  That is what :func:`brdfcl.data.merl.read_merl` returns (``MerlTable.brdf``)
and what BBM's MERL reader returns, and the fits agree with MERL-proxy tables on that scale in every
channel, so no conversion is applied.

    from bench import published            # or load bench/published.py by path
    published.load("sgd_bagher2012")["alum-bronze"]["alpha_r"]
    published.evaluate("abc_low2012_microfacet_e2", "gold-metallic-paint3", wi, wo)   # (3, n)
"""
from __future__ import annotations

import csv
from collections.abc import Callable
from functools import cache
from pathlib import Path

import numpy as np

DATA_DIR = Path(__file__).resolve().parent / "published"

_BAGHER = ("Bagher, Soler, Holzschuch 2012, 'Accurate fitting of measured reflectances using a Shifted Gamma "
           "micro-facet distribution', CGF 31(4), doi:10.1111/j.1467-8659.2012.03147.x")
_LOW = ("Low, Kronander, Ynnerman, Unger 2012, 'BRDF models for accurate and efficient rendering of glossy "
        "surfaces', ACM TOG 31(1), doi:10.1145/2077341.2077350, supplemental material")

MODELS: dict[str, str] = {
    "sgd_bagher2012": "SGD microfacet model (Lambertian + shifted-gamma D, fitted G1, modified Schlick F), "
                      "every parameter per RGB channel; " + _BAGHER,
    "abc_low2012_microfacet_e2": "ABC microfacet model, E2 fits (Lambertian + A (1 + B(1 - h.n))^-C, V-groove G, "
                                 "dielectric Fresnel, 1/pi as fitted); kd and A per channel, B, C, eta shared; "
                                 + _LOW,
    "abc_low2012_smooth_e2": "ABC smooth-surface model, E2 fits (Lambertian + A (1 + B |Dp|^2)^-C Q(theta_d)); "
                             "kd and A per channel, B, C, eta shared; " + _LOW,
}
"""The published models: name (= csv file stem) -> description with citation."""

Params = dict[str, float]

_EPS = float(np.finfo(np.float64).eps)


@cache
def _read(model: str) -> dict[str, Params]:
    if model not in MODELS:
        raise KeyError(f"unknown published model {model!r}; available: {', '.join(MODELS)}")
    path = DATA_DIR / f"{model}.csv"
    with open(path, newline="") as f:
        rows = csv.DictReader(line for line in f if not line.startswith("#"))
        out = {}
        for row in rows:
            name = row.pop("material")
            out[name] = {k: float(v) for k, v in row.items()}
    return out


def load(model: str) -> dict[str, Params]:
    """The published fits of ``model``: MERL material name -> {column: value} (columns as in the csv,
    per-channel ones suffixed ``_r``, ``_g``, ``_b``).  A fresh copy; the file is parsed once."""
    return {m: dict(p) for m, p in _read(model).items()}


def _rgb(p: Params, name: str) -> np.ndarray:
    """A per-channel parameter as a (3, 1) column, to broadcast against (n,) direction arrays."""
    return np.array([p[f"{name}_r"], p[f"{name}_g"], p[f"{name}_b"]], dtype=np.float64)[:, None]


def _halfway(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit half vector h = (wi + wo) / |wi + wo| and cos(theta_d) as the mean of wi.h and wo.h (BBM takes the
    mean so that round-off cannot break reciprocity)."""
    h = wi + wo
    with np.errstate(invalid="ignore", divide="ignore"):
        h = h / np.linalg.norm(h, axis=1, keepdims=True)
    cos_d = 0.5 * (np.einsum("ij,ij->i", wi, h) + np.einsum("ij,ij->i", wo, h))
    return h, cos_d


def _fresnel_dielectric(eta: float, c: np.ndarray) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a dielectric of index eta at cos = c, in Cook and Torrance's form:
    F = (1/2) (g - c)^2 / (g + c)^2 [1 + ((c (g + c) - 1) / (c (g - c) + 1))^2], g = sqrt(eta^2 + c^2 - 1)
    (g clamped at 0, F at 0, as BBM does)."""
    g = np.sqrt(np.maximum(eta * eta + c * c - 1.0, 0.0))
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return np.maximum(0.5 * a * a * (1.0 + b * b), 0.0)


def _polar_angle(v: np.ndarray) -> np.ndarray:
    """theta of unit vectors with z >= 0, as 2 asin(|v - n| / 2) (accurate near the normal)."""
    d = v.copy()
    d[:, 2] -= 1.0
    return 2.0 * np.arcsin(np.minimum(0.5 * np.linalg.norm(d, axis=1), 1.0))


Specular = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def _microfacet(p: Params, kd: str, wi: np.ndarray, wo: np.ndarray, up: np.ndarray, specular: Specular) -> np.ndarray:
    """The microfacet models' common form: kd / pi (per channel, column ``kd``) where both directions are
    up, plus specular(wi, wo, h, cos theta_d) / (pi cos theta_i cos theta_o) where both are strictly above
    the horizon (BBM's microfacet.h with the Cook normalisation pi)."""
    out = np.zeros((3, wi.shape[0]))
    out[:, up] = _rgb(p, kd) / np.pi
    spec = up & (wi[:, 2] > 0) & (wo[:, 2] > 0)
    wi, wo = wi[spec], wo[spec]
    h, cos_d = _halfway(wi, wo)
    out[:, spec] += specular(wi, wo, h, cos_d) / (np.pi * wi[:, 2] * wo[:, 2])
    return out


def _sgd(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """SGD model of Bagher et al. 2012 as BBM (bagher.h, ndf/sgd.h) evaluates it:

    f = rho_d / pi + rho_s D(h) G1(wi) G1(wo) F(cos theta_d) / (pi cos theta_i cos theta_o), per channel, with
    D = K_ap exp(-t) / t^p / (pi cos^4 theta_h), t = alpha + tan^2 theta_h / alpha (the shifted gamma
    distribution; K_ap its normalisation 1 / (alpha Gamma(1 - p, alpha)), published with the fit; D = 0
    where t^p <= machine epsilon), G1(v) = 1 + Lambda (1 - exp(c (theta_v - theta0)^k)) for theta_v > theta0
    and 1 otherwise (the paper's fitted shadowing), F = F0 + (1 - F0)(1 - cos theta_d)^5 - F1 cos theta_d
    (the paper's modified Schlick Fresnel)."""
    alpha, power = _rgb(p, "alpha"), _rgb(p, "p")
    lam, c, k, theta0 = _rgb(p, "Lambda"), _rgb(p, "c"), _rgb(p, "k"), _rgb(p, "theta0")

    def g1(v: np.ndarray) -> np.ndarray:
        theta = _polar_angle(v)
        above = theta > theta0
        x = np.where(above, theta - theta0, 1.0)       # any base > 0 where unused: no NaN from pow
        with np.errstate(over="ignore"):
            g = 1.0 + lam * (1.0 - np.exp(c * x**k))
        return np.where(above, g, 1.0)

    def specular(wi: np.ndarray, wo: np.ndarray, h: np.ndarray, cos_d: np.ndarray) -> np.ndarray:
        ch = h[:, 2]
        tan2 = np.maximum(1.0 - ch * ch, 0.0) / (ch * ch)
        t = alpha + tan2 / alpha
        den = t**power
        with np.errstate(divide="ignore", invalid="ignore"):
            p22 = np.where(den > _EPS, np.exp(-t) / den, 0.0)
        d = np.where(ch > 0, _rgb(p, "K_ap") * p22 / (np.pi * ch**4), 0.0)
        f0, f1 = _rgb(p, "F0"), _rgb(p, "F1")
        fresnel = f0 + (1.0 - f0) * (1.0 - cos_d) ** 5 - f1 * cos_d
        return _rgb(p, "rho_s") * d * g1(wi) * g1(wo) * fresnel

    return _microfacet(p, "rho_d", wi, wo, up, specular)


def _abc_microfacet(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """ABC microfacet model of Low et al. 2012 as fitted in their supplemental material (BBM's
    LowMicrofacetFit: lowmicrofacet.h with the Cook normalisation pi, ndf/low.h, vgroove.h, fresnel_cook.h):

    f = kd / pi + A S(h) G F(cos theta_d) / (pi cos theta_i cos theta_o), S = (1 + B (1 - cos theta_h))^-C
    (paper eq. 15's ABC curve), G = min(1, 2 cos theta_h cos theta_i / wi.h, 2 cos theta_h cos theta_o / wo.h)
    (V-groove), F the dielectric Fresnel of index eta.  The paper's eq. 15 has no 1/pi; the published fits
    were made with it (BBM's note; they match MERL only with it).  kd, A per channel; B, C, eta shared."""
    def specular(wi: np.ndarray, wo: np.ndarray, h: np.ndarray, cos_d: np.ndarray) -> np.ndarray:
        ch = h[:, 2]
        s = np.where(ch > 0, (1.0 + p["B"] * (1.0 - ch)) ** (-p["C"]), 0.0)
        ih, oh = np.einsum("ij,ij->i", wi, h), np.einsum("ij,ij->i", wo, h)
        g = np.minimum(1.0, np.minimum(2.0 * ch * wi[:, 2] / ih, 2.0 * ch * wo[:, 2] / oh))
        return _rgb(p, "A") * (s * g * _fresnel_dielectric(p["eta"], cos_d))

    return _microfacet(p, "kd", wi, wo, up, specular)


def _abc_smooth(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """ABC smooth-surface model of Low et al. 2012 as BBM (lowsmooth.h) evaluates it (paper eqs. 10, 12, 14
    as BBM cites them, with G = 1):

    f = kd / pi + A (1 + B |Dp|^2)^-C Q(cos theta_d), Dp = (wi + wo) projected on the surface plane,
    cos theta_d = sqrt(1 - |wi_xy - wo_xy|^2 / 4), Q the dielectric Fresnel of index eta.  No 1/pi and no
    1/(cos theta_i cos theta_o) in the specular term.  kd, A per channel; B, C, eta shared."""
    out = np.zeros((3, wi.shape[0]))
    wi, wo = wi[up], wo[up]
    dp2 = np.sum((wi[:, :2] + wo[:, :2]) ** 2, axis=1)
    cos_d = np.sqrt(np.maximum(1.0 - 0.25 * np.sum((wi[:, :2] - wo[:, :2]) ** 2, axis=1), 0.0))
    s = (1.0 + p["B"] * dp2) ** (-p["C"])
    out[:, up] = _rgb(p, "kd") / np.pi + _rgb(p, "A") * (s * _fresnel_dielectric(p["eta"], cos_d))
    return out


_EVAL = {
    "sgd_bagher2012": _sgd,
    "abc_low2012_microfacet_e2": _abc_microfacet,
    "abc_low2012_smooth_e2": _abc_smooth,
}


def evaluate(model: str, material: str, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """BRDF values (3, n) float64 in 1/sr (MERL's scaled RGB, as brdfcl's MERL reader) of the published fit of
    ``model`` for ``material`` at the unit directions ``wi``, ``wo`` (n, 3), z the surface normal, both
    pointing away from the surface.  0 where either direction is below the horizon (z < 0; the specular
    term of the microfacet models also needs z > 0).  Symmetric in wi, wo for every model.  The published
    SGD parameters are not constrained to give f >= 0 everywhere (G1 and F can dip below 0 at extreme
    angles); nothing is clamped, as in BBM."""
    fits = _read(model)
    if material not in fits:
        raise KeyError(f"{model}: no published fit for material {material!r}")
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    if wi.ndim != 2 or wi.shape[1] != 3 or wi.shape != wo.shape:
        raise ValueError(f"wi and wo must both have shape (n, 3), got {wi.shape} and {wo.shape}")
    up = (wi[:, 2] >= 0) & (wo[:, 2] >= 0)
    return _EVAL[model](fits[material], wi, wo, up)
