"""The float64 reference: gradients, normalisation, reciprocity, energy."""
import zlib

import numpy as np
import pytest
from scipy import integrate
from scipy.special import gamma, gammaincc

from brdfcl.data.geometry import table_geometry
from brdfcl.model.compose import Model
from brdfcl.model.lobes import REGISTRY
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.terms.ndf.sgd import sgd_consts
from brdfcl.model.terms.ndf.sgd import upper_gamma as _upper_gamma

LOBES = ["diffuse", "diffraction:hp", "diffraction:abc:schlick", "diffraction:gauss:conductor",
         "diffraction:hp:dielectric", "ggx:smith:schlick", "ggx:smith-hc:dielectric",
         "ggx:vcavity:conductor", "beckmann:smith:conductor", "beckmann:smith-hc:none",
         "sgd:vcavity:schlick", "epd:vcavity:dielectric", "epd:none:none"]


def random_values(model, rng, n):
    u = rng.random((n, model.n_free))
    return model.from_x(model.x_lo + u * (model.x_hi - model.x_lo))


def random_cells(rng, n):
    g = table_geometry()
    return Cells.from_geometry(g, rng.choice(np.flatnonzero(g.above_horizon), n, replace=False))


@pytest.mark.parametrize("spec", LOBES)
def test_gradients_match_finite_differences(spec):
    """>= 1,000 (parameter, cell) points per lobe; Richardson-extrapolated central differences."""
    rng = np.random.default_rng(zlib.crc32(spec.encode()))
    model = Model(spec)
    cells = random_cells(rng, 40)
    checked = 0
    for v in random_values(model, rng, 30):
        p, J = model.reference(cells, v)
        assert np.isfinite(p).all() and np.isfinite(J).all()
        for k, i in enumerate(model.free_index):
            def fd(h):
                vp, vm = v.copy(), v.copy()
                vp[i] += h
                vm[i] -= h
                return (model.reference(cells, vp, False) - model.reference(cells, vm, False)) / (2 * h)
            scale = max(abs(v[i]), 1e-3)
            # step shrinks where the value is stiff in this parameter (|d ln p / d ln v| >> 1)
            stiff = np.max(np.abs(fd(1e-6 * scale)) * scale / np.maximum(np.abs(p), 1e-300))
            h = 1e-4 * scale / max(1.0, stiff)
            d = (4 * fd(h / 2) - fd(h)) / 3
            # points where the parameter moves the value (relative sensitivity above 1e-6)
            sens = np.abs(d) * scale > 1e-6 * np.abs(p)
            sens &= np.abs(p) > 1e-200
            err = np.abs(J[..., k] - d)[sens]
            # floor: the rounding error of the differences themselves, ~ eps |p| / h
            floor = 1e-14 * np.abs(p[sens]) / h
            assert (err <= 1e-6 * np.abs(d[sens]) + floor).all(), \
                f"{model.names[i]}={v[i]:.4g}: worst {np.max(err / np.abs(d[sens])):.2e}"
            checked += sens.sum()
    assert checked >= 1000


def _hemisphere_integral(f, n=20000):
    # theta on a grid dense near 0 (sharp lobes): theta = (pi/2) u^3
    u = (np.arange(n) + 0.5) / n
    th = 0.5 * np.pi * u ** 3
    dth = 0.5 * np.pi * 3 * u ** 2 / n
    return 2 * np.pi * np.sum(f(th) * np.cos(th) * np.sin(th) * dth)


@pytest.mark.parametrize("ndf, params", [
    ("ggx", {"alpha": 1e-3}), ("ggx", {"alpha": 0.3}), ("ggx", {"alpha": 1.0}),
    ("beckmann", {"alpha": 1e-3}), ("beckmann", {"alpha": 0.5}),
    ("sgd", {"alpha": 0.01, "p": 0.5}), ("sgd", {"alpha": 0.2, "p": 1.6}), ("sgd", {"alpha": 1.0, "p": 1.0}),
    ("epd", {"beta": 0.02, "p": 0.5}), ("epd", {"beta": 0.3, "p": 2.0}), ("epd", {"beta": 0.1, "p": 1.0}),
])
def test_ndf_normalisation(ndf, params):
    term = REGISTRY["ndf"][ndf]
    consts = term.consts(**params) if term.consts else {}

    def D(th):
        c = Cells(np.sin(th), np.cos(th), np.ones_like(th), np.ones_like(th), np.ones_like(th))
        return term.reference(c, **params, **consts)[0]
    assert _hemisphere_integral(D) == pytest.approx(1.0, rel=2e-3)


@pytest.mark.parametrize("s, x", [(0.5, 0.01), (-0.6, 0.001), (-0.95, 0.5), (0.9, 2.0), (0.0, 0.1)])
def test_upper_gamma(s, x):
    G, dG = _upper_gamma(s, x)
    exact = integrate.quad(lambda t: t ** (s - 1) * np.exp(-t), x, np.inf, limit=200)[0]
    assert G == pytest.approx(exact, rel=1e-9)
    if s > 0:
        assert G == pytest.approx(gammaincc(s, x) * gamma(s), rel=1e-9)
    d = integrate.quad(lambda t: np.log(t) * t ** (s - 1) * np.exp(-t), x, np.inf, limit=200)[0]
    assert dG == pytest.approx(d, rel=1e-8, abs=1e-12)
    N = sgd_consts(0.1, 0.7)[0]["N"]
    assert np.isfinite(N) and N > 0


def _random_dirs(rng, n):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("spec", ["diffuse+diffraction:abc:conductor+ggx:smith-hc:schlick",
                                  "beckmann:smith:dielectric", "sgd:vcavity:none", "epd:vcavity:schlick"])
def test_reciprocity(spec):
    rng = np.random.default_rng(1)
    model = Model(spec)
    wi, wo = _random_dirs(rng, 5000), _random_dirs(rng, 5000)
    for v in random_values(model, rng, 5):
        a = model.reference(Cells.from_directions(wi, wo), v, False)
        b = model.reference(Cells.from_directions(wo, wi), v, False)
        np.testing.assert_allclose(a, b, rtol=1e-10)


@pytest.mark.parametrize("spec", ["ggx:smith:dielectric", "ggx:smith-hc:conductor", "beckmann:smith:schlick",
                                  "sgd:vcavity:none", "epd:vcavity:none", "diffuse"])
def test_albedo_at_most_one(spec):
    """Directional albedo <= 1 with amplitudes <= 1 (physically bounded settings)."""
    rng = np.random.default_rng(2)
    model = Model(spec)
    n_t, n_p = 400, 96
    u = (np.arange(n_t) + 0.5) / n_t
    th = 0.5 * np.pi * u ** 2
    dth = np.pi * u / n_t
    ph = (np.arange(n_p) + 0.5) * 2 * np.pi / n_p
    T, P = np.meshgrid(th, ph, indexing="ij")
    wi = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    dw = (np.sin(T) * dth[:, None] * (2 * np.pi / n_p)).ravel()
    for theta_o in (0.0, 0.6, 1.2, 1.5):
        wo = np.broadcast_to([np.sin(theta_o), 0.0, np.cos(theta_o)], wi.shape)
        for v in random_values(model, rng, 4):
            v[model.amplitude] = np.minimum(v[model.amplitude], 1.0)
            p = model.reference(Cells.from_directions(wi, wo), v, False)
            albedo = np.sum(p * wi[:, 2] * dw, axis=1)
            assert (albedo <= 1.0 + 5e-3).all(), (theta_o, albedo, model.as_dict(v))
