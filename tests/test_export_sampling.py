"""The importance sampling of brdfcl.report.export.sampling (used by the Mitsuba BSDF): the pdf is the
density that `sample` draws with, and sample weights are unbiased estimates of the albedo."""
import numpy as np
import pytest

from brdfcl.model.compose import Model
from brdfcl.model.synth import DEMO, demo_values
from brdfcl.report.export.sampling import Sampler


def _frame(w):
    t = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(t, w)
    x /= np.linalg.norm(x)
    return x, np.cross(w, x)


def _polar_grid(wi, n_s=1500, n_p=360):
    """Directions on the whole sphere in polar coordinates around the mirror direction of wi,
    refined near it (theta' = pi s^3), with their solid angles; and each one's s bin."""
    wr = np.array([-wi[0], -wi[1], wi[2]])
    x, y = _frame(wr)
    s = (np.arange(n_s) + 0.5) / n_s
    th = np.pi * s ** 3
    dth = 3.0 * np.pi * s ** 2 / n_s
    ph = (np.arange(n_p) + 0.5) / n_p * 2.0 * np.pi
    T, P = np.meshgrid(th, ph, indexing="ij")
    d = (np.sin(T)[..., None] * (np.cos(P)[..., None] * x + np.sin(P)[..., None] * y)
         + np.cos(T)[..., None] * wr).reshape(-1, 3)
    dw = (np.sin(T) * dth[:, None] * (2.0 * np.pi / n_p)).reshape(-1)
    return d, dw, wr, x, y


def _s_of(wo, wr):
    c = np.clip(wo @ wr, -1.0, 1.0)
    return np.cbrt(np.arccos(c) / np.pi)


CASES = [("synth-smooth-metal", 0.0), ("synth-smooth-metal", 50.0), ("synth-mirror", 20.0),
         ("synth-rough-metal", 70.0), ("synth-fabric", 35.0)]


@pytest.mark.parametrize("name,theta", CASES)
def test_pdf_is_the_density_of_sample(name, theta):
    spec, params = DEMO[name]
    model = Model(spec)
    sm = Sampler(model, demo_values(model, params))
    wi = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
    d, dw, wr, _, _ = _polar_grid(wi)
    W = np.broadcast_to(wi, d.shape)
    f, pdf = sm.eval_pdf(W, d)
    total = float(np.sum(pdf * dw))
    albedo = np.sum(f * dw, axis=1)

    rng = np.random.default_rng(7)
    n = 200_000
    wo, p, weight, _ = sm.sample(np.broadcast_to(wi, (n, 3)), rng.random(n), rng.random((n, 2)))
    kept = p > 0
    # the pdf integrates to the fraction of draws that are kept (1 up to the lost half-vectors)
    frac = kept.mean()
    print(f"{name} {theta}: integral of pdf {total:.4f}, kept {frac:.4f}")
    assert abs(total - frac) < 4 * np.sqrt(frac * (1 - frac) / n) + 2e-3, (total, frac)
    assert total > 0.75 and total <= 1.0 + 2e-3
    # sample returns the pdf of its direction, and weight = eval / pdf
    f_s, p_s = sm.eval_pdf(np.broadcast_to(wi, (n, 3))[kept], wo[kept])
    np.testing.assert_allclose(p[kept], p_s, rtol=1e-12)
    np.testing.assert_allclose(weight[:, kept], f_s / p_s, rtol=1e-12)
    assert np.all(weight[:, ~kept] == 0)
    # unbiased: the mean weight is the directional albedo integrated on the grid
    est = weight.mean(axis=1)
    err = weight.std(axis=1) / np.sqrt(n)
    assert np.all(np.abs(est - albedo) < 5 * err + 2e-3 * albedo), (est, albedo, err)
    # the draws follow the pdf: histogram in the radial coordinate around the mirror direction
    edges = np.linspace(0.0, 1.0, 31)
    obs = np.histogram(_s_of(wo[kept], wr), edges)[0]
    s_grid = _s_of(d, wr)
    expect = np.histogram(s_grid, edges, weights=pdf * dw)[0] * n
    big = expect > 100
    assert np.all(np.abs(obs[big] - expect[big]) < 5 * np.sqrt(expect[big]) + 0.01 * expect[big]), \
        (obs, expect.round())


def test_proposals_follow_the_lobes():
    spec, params = DEMO["synth-smooth-metal"]
    model = Model(spec)
    sm = Sampler(model, demo_values(model, params))
    kinds = {(c.lobe, c.channel): c for c in sm.components}
    assert kinds[("ct", None)].kind == "ggx" and kinds[("ct", None)].alpha == pytest.approx(0.02)
    # hp PSD ~ GGX in sin(theta_h) with alpha = lambda a / 2 near the peak
    for ch, lam in enumerate(model.lambdas):
        assert kinds[("diffraction", ch)].alpha == pytest.approx(lam * 0.8 / 2, rel=0.05)
    w = np.array([c.weight for c in sm.components])
    assert w.sum() == pytest.approx(1.0) and w[0] >= 0.04
    # sgd / epd fall back on a GGX proposal, abc / gauss PSDs as well
    for spec in ("diffuse+diffraction:abc+sgd", "diffraction:gauss+epd"):
        m = Model(spec)
        s = Sampler(m, m.defaults())
        assert all(c.kind in ("cosine", "ggx") and (c.kind == "cosine" or c.alpha > 0)
                   for c in s.components)


def test_below_horizon_is_zero():
    model = Model("diffuse+ggx")
    sm = Sampler(model, model.defaults())
    wi = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, -0.8]])
    wo = np.array([[0.6, 0.0, -0.8], [0.0, 0.0, 1.0]])
    f, p = sm.eval_pdf(wi, wo)
    assert np.all(f == 0) and np.all(p == 0)
    wo, p, w, _ = sm.sample(wi[1:], [0.3], [[0.2, 0.7]])
    assert p[0] == 0 and np.all(w == 0)
