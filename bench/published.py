"""Published per-material fits of BRDF models to the MERL materials, to compare brdfcl's fits with.

* ``sgd_bagher2012``: the Shifted Gamma Distribution microfacet model of Bagher, Soler, Holzschuch,
  "Accurate fitting of measured reflectances using a Shifted Gamma micro-facet distribution",
  Computer Graphics Forum 31(4), 2012.
* ``abc_low2012_microfacet_e2`` and ``abc_low2012_smooth_e2``: the ABC microfacet and smooth-surface
  models of Low (Löw), Kronander, Ynnerman, Unger, "BRDF models for accurate and efficient rendering of
  glossy surfaces", ACM TOG 31(1), 2012, fitted with the paper's E2 (cosine-weighted log) metric.
* ``ashikhminshirley_low2012_e1``/``_e2`` and ``cooktorrance_low2012_e1``/``_e2``: the same paper's fits of
  Ashikhmin-Shirley and Cook-Torrance with its E1 and E2 metrics (supplemental material); 100 materials each.
* ``*_ngan2005``: the fits of Ngan, Durand, Matusik, "Experimental analysis of BRDF models", Eurographics
  Symposium on Rendering 2005, of Ashikhmin-Shirley, Blinn-Phong, Cook-Torrance, He et al., Lafortune,
  Ward and Ward-Duer; 86 materials each (the paper's set), each with a Lambertian term.

The numbers (``bench/published/<model>.csv``) are the fits that the BSDF benchmark BBM
(github.com/bsdfbenchmark/bbm, commit 9807fb38d7ab51802f3a0fe0f65cf763cb01a0f4, ``fits/*.fit``) collected
from the papers' published material, copied verbatim; each file's ``#`` header names its source and the
meaning of every column.  :func:`evaluate` is the model exactly as BBM evaluates these fits
(``include/bsdfmodel/bagher.h``, ``lowmicrofacet.h``, ``low.h``, ``lowsmooth.h``, ``ngan.h`` and the
headers they use), which is what the numbers were fitted with where the paper's text differs (the 1/pi of
the ABC microfacet fits), and follows BBM also where it may not be (Ngan's "Blinn-Phong" is BBM's Phong
lobe about the mirror direction; see its csv header).  Checked against BBM's own C++ code (native backbone,
bench/published_bbm_check.cpp) at 300 direction pairs (a third near the mirror direction) for every
material of each file, max relative difference per model (doubleRGB unless said; tests/test_published.py
holds a subset):

* ashikhminshirley_low2012_e1 5.1e-16, ashikhminshirley_low2012_e2 5.7e-16, cooktorrance_low2012_e1 6.1e-16,
  cooktorrance_low2012_e2 5.9e-16
* ashikhminshirley_ngan2005 5.5e-16, blinnphong_ngan2005 5.2e-16, cooktorrance_ngan2005 7.7e-16,
  ward_ngan2005 5.0e-16, wardduer_ngan2005 6.3e-16
* he_ngan2005 5.7e-14 (erfc, exp and a Taylor sum of up to 64 terms per channel)
* lafortune_ngan2005 1.6e-14 against BBM in long double (its doubleRGB result is NaN: n up to 16600)
* sgd_bagher2012 6.7e-13 (the fitted shadowing's exponents k, up to 856, amplify the round-off of theta_v),
  abc_low2012_microfacet_e2 6.4e-16, abc_low2012_smooth_e2 4.4e-16

Scale: values are BRDFs in 1/sr on MERL's scaled RGB, the stored MERL numbers times (1/1500, 1.15/1500,
1.66/1500) for (R, G, B).  That is what :func:`brdfcl.data.merl.read_merl` returns (``MerlTable.brdf``)
and what BBM's MERL reader returns, and the fits of Bagher et al. and Low et al. agree with MERL-proxy
tables on that scale in every channel, so no conversion is applied to them.  Ngan et al.'s numbers are on
MERL / 1500 in every channel; :func:`evaluate` multiplies their G and B by 1.15 and 1.66 (:data:`RGB_SCALE`;
BBM does not).

    from bench import published            # or load bench/published.py by path
    published.load("sgd_bagher2012")["alum-bronze"]["alpha_r"]
    published.evaluate("abc_low2012_microfacet_e2", "gold-metallic-paint3", wi, wo)   # (3, n)
"""
from __future__ import annotations

import csv
import math
from collections.abc import Callable
from functools import cache
from pathlib import Path

import numpy as np

DATA_DIR = Path(__file__).resolve().parent / "published"

_BAGHER = ("Bagher, Soler, Holzschuch 2012, 'Accurate fitting of measured reflectances using a Shifted Gamma "
           "micro-facet distribution', CGF 31(4), doi:10.1111/j.1467-8659.2012.03147.x")
_LOW = ("Low, Kronander, Ynnerman, Unger 2012, 'BRDF models for accurate and efficient rendering of glossy "
        "surfaces', ACM TOG 31(1), doi:10.1145/2077341.2077350, supplemental material")
_NGAN = ("Ngan, Durand, Matusik 2005, 'Experimental analysis of BRDF models', Eurographics Symposium on Rendering, "
         "dl.acm.org/doi/10.5555/2383654.2383671, supplemental material; fitted on MERL / 1500 in every channel")
_ASHIKHMIN = "Ashikhmin, Shirley 2000, 'An anisotropic Phong BRDF model', JGT 5(2)"
_COOK = "Cook, Torrance 1982, 'A reflectance model for computer graphics', ACM TOG 1(1)"

MODELS: dict[str, str] = {
    "sgd_bagher2012": "SGD microfacet model (Lambertian + shifted-gamma D, fitted G1, modified Schlick F), "
                      "every parameter per RGB channel; " + _BAGHER,
    "abc_low2012_microfacet_e2": "ABC microfacet model, E2 fits (Lambertian + A (1 + B(1 - h.n))^-C, V-groove G, "
                                 "dielectric Fresnel, 1/pi as fitted); kd and A per channel, B, C, eta shared; "
                                 + _LOW,
    "abc_low2012_smooth_e2": "ABC smooth-surface model, E2 fits (Lambertian + A (1 + B |Dp|^2)^-C Q(theta_d)); "
                             "kd and A per channel, B, C, eta shared; " + _LOW,
    "ashikhminshirley_low2012_e1": "isotropic Ashikhmin-Shirley specular lobe with the dielectric Fresnel, E1 fits "
                                   "(Lambertian + ks (n + 1) / (8 pi) cos^n theta_h F / (wi.h max(cos theta_i, "
                                   "cos theta_o))); kd, ks per channel; " + _ASHIKHMIN + "; fits " + _LOW,
    "ashikhminshirley_low2012_e2": "as ashikhminshirley_low2012_e1, E2 fits; " + _ASHIKHMIN + "; fits " + _LOW,
    "cooktorrance_low2012_e1": "Cook-Torrance (Lambertian + ks D G F / (pi cos theta_i cos theta_o), Beckmann D "
                               "without 1/pi, V-groove G, dielectric Fresnel), E1 fits; kd, ks per channel; "
                               + _COOK + "; fits " + _LOW,
    "cooktorrance_low2012_e2": "as cooktorrance_low2012_e1, E2 fits; " + _COOK + "; fits " + _LOW,
    "ashikhminshirley_ngan2005": "isotropic Ashikhmin-Shirley specular lobe with Schlick's Fresnel (Lambertian + ks "
                                 "(n + 1) / (8 pi) cos^n theta_h F / (wi.h max(cos theta_i, cos theta_o))); "
                                 + _ASHIKHMIN + "; fits " + _NGAN,
    "blinnphong_ngan2005": "normalised Phong lobe as BBM evaluates Ngan's Blinn-Phong fits (Lambertian + ks (n + 2) "
                           "/ (2 pi) max(R(wi).wo, 0)^n, R the mirror reflection); fits " + _NGAN,
    "cooktorrance_ngan2005": "Cook-Torrance with Schlick's Fresnel (Lambertian + ks D G F / (pi cos theta_i cos "
                             "theta_o), Beckmann D with 1/pi, V-groove G); " + _COOK + "; fits " + _NGAN,
    "he_ngan2005": "directional specular term of He, Torrance, Sillion, Greenberg 1991, 'A comprehensive physical "
                   "model for light reflection', SIGGRAPH, doi:10.1145/127719.122738 (Lambertian + ks F S G D / "
                   "(pi cos theta_i cos theta_o), BBM's NganHe variant); fits " + _NGAN,
    "lafortune_ngan2005": "isotropic one-lobe Lafortune (Lafortune, Foo, Torrance, Greenberg 1997, 'Non-linear "
                          "approximation of reflectance functions', SIGGRAPH) with Ngan's normalisation (Lambertian "
                          "+ ks (n + 2) / (2 pi) max(C.(wi*wo), 0)^n / max(Cz^2, Cxy^2)^(n/2)); fits " + _NGAN,
    "ward_ngan2005": "isotropic Ward (Ward 1992, 'Measuring and modeling anisotropic reflection', SIGGRAPH) "
                     "(Lambertian + ks exp(-tan^2 theta_h / alpha^2) / (4 pi alpha^2 sqrt(cos theta_i cos "
                     "theta_o))); fits " + _NGAN,
    "wardduer_ngan2005": "isotropic Ward with Duer's normalisation (Duer 2006, 'An improved normalization for the "
                         "Ward reflectance model', JGT 11(1)) (Lambertian + ks exp(-tan^2 theta_h / alpha^2) / (4 pi "
                         "alpha^2 cos theta_i cos theta_o)); fits " + _NGAN,
}
"""The published models: name (= csv file stem) -> description with citation."""

RGB_SCALE: dict[str, tuple[float, float, float]] = {m: (1.0, 1.15, 1.66) for m in MODELS if m.endswith("_ngan2005")}
"""Per-channel factors from a model's published numbers to MERL's scaled RGB, for the fits made on another scale
(Ngan et al.'s: MERL's stored numbers / 1500 in every channel, see the csv headers); 1 where absent."""

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


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a.b, summed in x, y, z order as BBM's dot (so that round-off matches where powers amplify it)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _halfway(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit half vector h = (wi + wo) / |wi + wo| and cos(theta_d) as the mean of wi.h and wo.h (BBM takes the
    mean so that round-off cannot break reciprocity)."""
    h = wi + wo
    with np.errstate(invalid="ignore", divide="ignore"):
        h = h * (1.0 / np.sqrt(_dot(h, h)))[:, None]          # BBM's normalize: v * rsqrt(v.v)
    cos_d = 0.5 * (_dot(wi, h) + _dot(wo, h))
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
        ih, oh = _dot(wi, h), _dot(wo, h)
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


def _fresnel_schlick(f0: float, c: np.ndarray) -> np.ndarray:
    """Schlick's Fresnel F = F0 + (1 - F0)(1 - c)^5, F0 the reflectance at normal incidence (BBM's
    fresnel_schlick.h)."""
    return f0 + (1.0 - f0) * (1.0 - c) ** 5


def _lambert_plus(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray, spec: np.ndarray,
                  specular: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
    """kd / pi where both directions are up (z >= 0), plus ks * specular(wi, wo) (per channel, columns ``kd`` and
    ``ks``) on the pairs ``spec`` (each model's own horizon test, as in BBM)."""
    out = np.zeros((3, wi.shape[0]))
    out[:, up] = _rgb(p, "kd") / np.pi
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out[:, spec] += _rgb(p, "ks") * specular(wi[spec], wo[spec])
    return out


def _ashikhmin_shirley(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray,
                       fresnel: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Isotropic Ashikhmin-Shirley specular lobe as BBM (ashikhminshirley.h) evaluates it, z > 0 for both:
    ks (n + 1) / (8 pi) cos(theta_h)^n F(wi.h) / (wi.h max(cos theta_i, cos theta_o)), h = (wi + wo) / |wi + wo|."""
    n = p["n"]

    def specular(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        h, _ = _halfway(wi, wo)
        ih = _dot(h, wi)
        den = ih * np.maximum(wi[:, 2], wo[:, 2])
        return (n + 1.0) / (8.0 * np.pi) * h[:, 2] ** n * fresnel(ih) / den

    return _lambert_plus(p, wi, wo, up, up & (wi[:, 2] > 0) & (wo[:, 2] > 0), specular)


def _as_low(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Low et al.'s Ashikhmin-Shirley (BBM low.h): the isotropic lobe of :func:`_ashikhmin_shirley` with the
    dielectric Fresnel of index eta (Cook-Torrance form); kd, ks per channel; n, eta shared."""
    return _ashikhmin_shirley(p, wi, wo, up, lambda c: _fresnel_dielectric(p["eta"], c))


def _as_ngan(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Ngan et al.'s Ashikhmin-Shirley (BBM ngan.h): the isotropic lobe of :func:`_ashikhmin_shirley` with
    Schlick's Fresnel of normal reflectance F0; kd, ks per channel; n, F0 shared."""
    return _ashikhmin_shirley(p, wi, wo, up, lambda c: _fresnel_schlick(p["F0"], c))


def _beckmann(m: float, h: np.ndarray) -> np.ndarray:
    """Beckmann D without the 1/pi (BBM's ndf::beckmann, Normalize = false): exp(-tan^2 theta_h / m^2) / (m^2
    cos^4 theta_h), tan^2 theta_h / m^2 formed as |h_xy / m|^2 / cos^2 theta_h; 0 where cos theta_h <= 0."""
    ch = h[:, 2]
    c2 = ch * ch
    return np.where(ch > 0, np.exp(-((h[:, 0] / m) ** 2 + (h[:, 1] / m) ** 2) / c2) / (m * m * c2 * c2), 0.0)


def _cook_torrance(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray, normalised: bool,
                   fresnel: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Cook-Torrance as BBM (cooktorrance.h, microfacet.h) evaluates it: kd / pi + ks D(h) G F(cos theta_d) /
    (pi cos theta_i cos theta_o), D Beckmann of roughness m (with an extra 1/pi if ``normalised``), G the V-groove
    min(1, 2 cos theta_h cos theta_i / wi.h, 2 cos theta_h cos theta_o / wo.h), cos theta_d the mean of wi.h and
    wo.h."""
    def specular(wi: np.ndarray, wo: np.ndarray, h: np.ndarray, cos_d: np.ndarray) -> np.ndarray:
        ch = h[:, 2]
        d = _beckmann(p["m"], h)
        if normalised:
            d = d / np.pi
        ih, oh = _dot(wi, h), _dot(wo, h)
        g = np.minimum(1.0, np.minimum(2.0 * ch * wi[:, 2] / ih, 2.0 * ch * wo[:, 2] / oh))
        return _rgb(p, "ks") * (d * g * fresnel(cos_d))

    return _microfacet(p, "kd", wi, wo, up, specular)


def _ct_low(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Low et al.'s Cook-Torrance (BBM low.h = cooktorrance.h): Beckmann D without 1/pi, dielectric Fresnel of
    index eta; kd, ks per channel; m, eta shared."""
    return _cook_torrance(p, wi, wo, up, False, lambda c: _fresnel_dielectric(p["eta"], c))


def _ct_ngan(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Ngan et al.'s Cook-Torrance (BBM ngan.h): Beckmann D with 1/pi, Schlick's Fresnel of normal reflectance F0
    (BBM's 'eta'); kd, ks per channel; m, F0 shared."""
    return _cook_torrance(p, wi, wo, up, True, lambda c: _fresnel_schlick(p["F0"], c))


def _phong_ngan(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Ngan et al.'s 'Blinn-Phong' as BBM evaluates it (ngan.h: an alias of phong.h, the modified Phong model):
    kd / pi + ks (n + 2) / (2 pi) max(R(wi).wo, 0)^n, R(wi) = (-x, -y, z) the mirror direction, z >= 0 for both.
    Not Blinn's cos(theta_h)^n; see the csv header."""
    n = p["n"]

    def specular(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        cos_a = np.maximum(-wi[:, 0] * wo[:, 0] - wi[:, 1] * wo[:, 1] + wi[:, 2] * wo[:, 2], 0.0)
        return (n + 2.0) * (0.5 / np.pi) * cos_a**n

    return _lambert_plus(p, wi, wo, up, up, specular)


def _lafortune_ngan(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Ngan et al.'s Lafortune (BBM ngan.h, lafortune.h), z > 0 for both:

    kd / pi + ks (n + 2) / (2 pi) max(Cxy (x_i x_o + y_i y_o) + Cz z_i z_o, 0)^n / max(Cz^2, Cxy^2)^(n/2).
    n reaches 16600, where both powers leave float64's range (BBM's doubleRGB result is NaN there); evaluated as
    (max(., 0) / sqrt(max(Cz^2, Cxy^2)))^n, a base in [0, 1], in np.longdouble (80-bit on x86-64, as BBM's long
    double configuration; float64 where numpy has no wider type, then ~n eps relative)."""
    n, cxy, cz = p["n"], p["Cxy"], p["Cz"]
    ld = np.longdouble

    def specular(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        a, b = wi.astype(ld), wo.astype(ld)
        lobe = np.maximum(ld(cxy) * a[:, 0] * b[:, 0] + ld(cxy) * a[:, 1] * b[:, 1] + ld(cz) * a[:, 2] * b[:, 2], 0)
        base = lobe / np.sqrt(np.maximum(ld(cz) * ld(cz), ld(cxy) * ld(cxy)))
        return ((ld(n) + 2) * ld(0.5) / ld(np.pi) * base ** ld(n)).astype(np.float64)

    return _lambert_plus(p, wi, wo, up, up & (wi[:, 2] > 0) & (wo[:, 2] > 0), specular)


def _ward(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray, duer: bool) -> np.ndarray:
    """Isotropic Ward as BBM (ward.h, wardduer.h) evaluates it, z >= 0 for both: kd / pi + ks exp(-tan^2 theta_h /
    alpha^2) / (4 pi alpha^2 sqrt(cos theta_i cos theta_o)), with cos theta_i cos theta_o instead of its square root
    for Duer's normalisation; tan^2 theta_h / alpha^2 = |H_xy / alpha|^2 / H_z^2, H = wi + wo.  (Infinite where a
    direction lies exactly in the horizon, as in BBM.)"""
    alpha = p["alpha"]

    def specular(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        h = wi + wo
        cos_io = wi[:, 2] * wo[:, 2]
        norm = 4.0 * np.pi * (cos_io if duer else np.sqrt(cos_io)) * alpha * alpha
        expo = ((h[:, 0] / alpha) ** 2 + (h[:, 1] / alpha) ** 2) / h[:, 2] ** 2
        return np.exp(-expo) / norm

    return _lambert_plus(p, wi, wo, up, up, specular)


_ERFC = np.frompyfunc(math.erfc, 1, 1)


def _erfc(x: np.ndarray) -> np.ndarray:
    """erfc elementwise (the C library's, through Python's math.erfc, as BBM's std::erfc)."""
    return _ERFC(x).astype(np.float64)


HE_WAVELENGTH = np.array([0.645, 0.526, 0.444])[:, None]
"""BBM's wavelengths of the R, G, B channels in micrometres (its rgb configurations), the He model's lambda."""
_HE_TAYLOR_TERMS, _HE_NEWTON_STEPS, _HE_ROUGH_G = 64, 4, 18.0


def _he_shadowing(tau: float, sigma: float, v: np.ndarray) -> np.ndarray:
    """He et al.'s S(v) (eqs. 24-25 with the errata's exponential, BBM he.h S1): with a = tau cot(theta) /
    (2 sigma), e = erfc(a) / 2, Lambda = exp(-a^2) / (2 sqrt(pi) a) - e, S = (1 - e) / (1 + Lambda); 1 if
    sigma < machine epsilon."""
    if sigma < _EPS:
        return np.ones(v.shape[0])
    tan = np.sqrt(np.maximum(1.0 - v[:, 2] * v[:, 2], 0.0)) / v[:, 2]
    a = tau * (1.0 / tan) / (2.0 * sigma)
    e = 0.5 * _erfc(a)
    lam = 0.5 / math.sqrt(np.pi) / a * np.exp(-(a**2)) - e
    return (1.0 - e) / (lam + 1.0)


def _he_geometry(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """He et al.'s geometrical factor G (eq. 76) in BBM's closed form: with v = wi + wo and k = -wi.wo,
    G = (|v|^2 / v_z)^2 ((s_r.k_i)^2 + (p_r.k_i)^2)((s_i.k_r)^2 + (p_i.k_r)^2) / |k_i x k_r|^4, the dots
    written out as (x_i y_o - y_i x_o)^2 + (z_o + k z_i)^2 etc. over (1 - z_i^2)(1 - z_o^2); 1 where
    (1 - k^2)^2 <= machine epsilon."""
    v = wi + wo
    v_scale = (np.sum(v * v, axis=1) / v[:, 2]) ** 2
    kixn2, krxn2 = 1.0 - wi[:, 2] * wi[:, 2], 1.0 - wo[:, 2] * wo[:, 2]
    k = -_dot(wi, wo)
    sikr = wo[:, 1] * wi[:, 0] - wo[:, 0] * wi[:, 1]
    srki = wi[:, 1] * wo[:, 0] - wi[:, 0] * wo[:, 1]
    pikr, prki = wo[:, 2] + k * wi[:, 2], wi[:, 2] + k * wo[:, 2]
    den = (1.0 - k * k) ** 2
    nom = (sikr**2 + pikr**2) * (srki**2 + prki**2) / (krxn2 * kixn2)
    return np.where(den > _EPS, v_scale * nom / den, 1.0)


def _he_sigma(tau: float, sigma: float, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """He et al.'s apparent roughness (eqs. 80-83, BBM he.h sigma): sigma / sqrt(1 + x^2), x the root of
    x exp(x^2 / 2) = (K_i + K_o) / sqrt(8 pi), K = tan(theta) erfc(tau / (2 sigma tan theta)) (0 where
    tan theta <= eps), by 4 Newton steps from x = f0 (f0 <= 1) or sqrt(2 ln f0); 0 if sigma <= eps."""
    if sigma <= _EPS:
        return np.zeros(wi.shape[0])

    def k(v: np.ndarray) -> np.ndarray:
        t = np.sqrt(np.maximum(1.0 - v[:, 2] * v[:, 2], 0.0)) / v[:, 2]
        return np.where(t > _EPS, t * _erfc(tau / (2.0 * sigma * t)), 0.0)

    f0 = (1.0 / math.sqrt(8.0 * np.pi)) * (k(wi) + k(wo))
    with np.errstate(divide="ignore"):
        x = np.where(f0 <= 1.0, f0, np.sqrt(np.maximum(2.0 * np.log(f0), 0.0)))
    for _ in range(_HE_NEWTON_STEPS):
        expn = np.exp(0.5 * x * x)
        grad = (1.0 + x * x) * expn
        x = x - np.where(grad > _EPS, (x * expn - f0) / grad, 0.0)
    return sigma / np.sqrt(np.maximum(1.0 + x * x, 0.0))


def _he_distribution(tau: float, sigma: float, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """He et al.'s D (eqs. 78-79, 84) per channel as BBM's NganHe evaluates it (Westin et al.'s eq. 78):
    pi^2 tau^2 / (4 lambda^2) sum_m g^m / (m! m) exp(-g - v_xy^2 tau^2 pi^2 / (lambda^2 m)),
    g = (2 pi sigma_apparent (cos theta_i + cos theta_o) / lambda)^2, v_xy = (wi + wo)_xy.  The sum stops (for all
    channels together) after the first term below machine epsilon that is smaller than the one before, at most 64
    terms; where min over channels of g exceeds 18 the rough approximation exp(-v_xy^2 tau^2 pi^2 / (lambda^2 g)) / g
    is blended in linearly, fully from g = 19 on (then no sum)."""
    lam = HE_WAVELENGTH
    vxy2 = np.sum((wi[:, :2] + wo[:, :2]) ** 2, axis=1)
    g = (2.0 * np.pi * _he_sigma(tau, sigma, wi, wo) * (wi[:, 2] + wo[:, 2]) / lam) ** 2
    tau2 = tau**2
    norm = 0.25 * np.pi * np.pi * tau2 / lam**2
    base = vxy2 * tau2 / 4.0 * (4.0 * np.pi * np.pi) / lam**2
    gmin = g.min(axis=0)
    approx = gmin > _HE_ROUGH_G
    with np.errstate(divide="ignore", invalid="ignore"):
        rough = np.where(approx, np.exp(-base / g) / g, 0.0)
    weight = np.where(approx, np.clip(gmin - _HE_ROUGH_G, 0.0, 1.0), 0.0)
    total = np.zeros_like(g)
    live = np.flatnonzero(~(gmin - 1.0 > _HE_ROUGH_G))           # the pairs whose sum has not converged
    g_l, base_l = g[:, live], base[:, live]
    s_l, gm, term = np.zeros_like(g_l), np.ones_like(g_l), np.zeros_like(g_l)
    for m in range(1, _HE_TAYLOR_TERMS + 1):
        if live.size == 0:
            break
        last = term
        gm = gm * (g_l / m)
        term = np.exp(-g_l - base_l / m) * gm / m
        s_l = s_l + term
        tmin = np.minimum(np.minimum(term[0], term[1]), term[2])
        done = (tmin < _EPS) & (tmin < np.minimum(np.minimum(last[0], last[1]), last[2]))
        total[:, live[done]] = s_l[:, done]
        keep = ~done
        live, g_l, base_l, s_l, gm, term = live[keep], g_l[:, keep], base_l[:, keep], s_l[:, keep], gm[:, keep], \
            term[:, keep]
    total[:, live] = s_l
    blend = np.where(weight == 1.0, rough, total + weight * (rough - total))     # std::lerp
    return norm * blend


def _he_ngan(p: Params, wi: np.ndarray, wo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Ngan et al.'s He-Torrance-Sillion-Greenberg specular term as BBM evaluates it (ngan.h nganhe: he.h's
    he_base with the Cook-Torrance dielectric Fresnel, the errata's eq. 25 and Westin et al.'s eq. 78), z > 0 for
    both:

    kd / pi + ks F(c) S(wi) S(wo) G D / (pi cos theta_i cos theta_o), c = sqrt((1 + wi.wo) / 2), F the dielectric
    Fresnel of index eta, S :func:`_he_shadowing`, G :func:`_he_geometry`, D :func:`_he_distribution` (per
    channel at BBM's wavelengths); tau, sigma in micrometres.  kd, ks per channel; tau, sigma, eta shared."""
    tau, sigma = p["tau"], p["sigma"]

    def specular(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        c = np.sqrt(np.maximum((1.0 + _dot(wi, wo)) / 2.0, 0.0))
        s = _he_shadowing(tau, sigma, wi) * _he_shadowing(tau, sigma, wo)
        norm = 1.0 / (np.pi * wi[:, 2] * wo[:, 2])
        return norm * _fresnel_dielectric(p["eta"], c) * s * _he_geometry(wi, wo) * _he_distribution(tau, sigma,
                                                                                                    wi, wo)

    return _lambert_plus(p, wi, wo, up, up & (wi[:, 2] > 0) & (wo[:, 2] > 0), specular)


_EVAL = {
    "sgd_bagher2012": _sgd,
    "abc_low2012_microfacet_e2": _abc_microfacet,
    "abc_low2012_smooth_e2": _abc_smooth,
    "ashikhminshirley_low2012_e1": _as_low,
    "ashikhminshirley_low2012_e2": _as_low,
    "cooktorrance_low2012_e1": _ct_low,
    "cooktorrance_low2012_e2": _ct_low,
    "ashikhminshirley_ngan2005": _as_ngan,
    "blinnphong_ngan2005": _phong_ngan,
    "cooktorrance_ngan2005": _ct_ngan,
    "he_ngan2005": _he_ngan,
    "lafortune_ngan2005": _lafortune_ngan,
    "ward_ngan2005": lambda p, wi, wo, up: _ward(p, wi, wo, up, duer=False),
    "wardduer_ngan2005": lambda p, wi, wo, up: _ward(p, wi, wo, up, duer=True),
}


def evaluate(model: str, material: str, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """BRDF values (3, n) float64 in 1/sr (MERL's scaled RGB, as brdfcl's MERL reader) of the published fit of
    ``model`` for ``material`` at the unit directions ``wi``, ``wo`` (n, 3), z the surface normal, both
    pointing away from the surface.  0 where either direction is below the horizon (z < 0; the specular
    term of the microfacet models also needs z > 0, as BBM's tests differ per model).  Symmetric in wi, wo for
    every model.  Ngan et al.'s fits times :data:`RGB_SCALE`.  The published
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
    f = _EVAL[model](fits[material], wi, wo, up)
    if model in RGB_SCALE:
        f *= np.array(RGB_SCALE[model])[:, None]
    return f
