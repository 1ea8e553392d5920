"""Heavy-tailed reflection lobes: GTR (ndf/gtr.py), ABC (ndf/abc.py) and their Smith
shadowing (shadowing/smith_gtr.py, smith_abc.py).  Their Jacobians and kernels are checked with every
other term by tests/test_every_term.py; here: GTR at gamma = 2 is GGX, both normalisations by
quadrature across the parameter box, reciprocity of a full lobe, the weak white furnace of the
Smith terms within the error bench/lambda_gtr.py measured, and the model strings."""
import numpy as np
import pytest

from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.terms import REGISTRY

GTR, ABC = REGISTRY["ndf"]["gtr"], REGISTRY["ndf"]["abc"]
G1_ERROR = 1e-4
"""The largest relative error of G1 for theta_o <= 80 deg over the parameter box, as measured by
bench/lambda_gtr.py (bench/results/lambda_gtr.md: 4.2e-5 for GTR, 5.9e-5 for ABC)."""


def f64(**p):
    return {k: np.float64(v) for k, v in p.items()}


def ndf(term, t, **p):
    """D at tan theta_m = t (an array), float64, host constants included."""
    p = f64(**p)
    ch = 1.0 / np.sqrt(1.0 + t * t)
    one = np.ones_like(t)
    v, _ = term.reference(Cells(t * ch, ch, one, one, one), **p, **term.consts(**p))
    return v


def panels(lo, hi, n_panels=300, order=20):
    """Composite Gauss-Legendre nodes and weights on [lo, hi]."""
    x, w = np.polynomial.legendre.leggauss(order)
    edges = np.linspace(lo, hi, n_panels + 1)
    half = np.diff(edges)[:, None] / 2
    return ((edges[:-1, None] + half * (x + 1)).ravel(), (half * w).ravel())


def peak_log_slope(term, p):
    """ln tan theta where the distribution's peak falls off (alpha, or sqrt(2 / B))."""
    return np.log(p["alpha"]) if term is GTR else 0.5 * np.log(2.0 / p["B"])


def random_directions(rng, n):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 1e-3
    return v / np.linalg.norm(v, axis=1, keepdims=True)


# --- GTR at gamma = 2 is GGX --------------------------------------------------------------------------
def test_gtr_at_gamma_2_is_ggx():
    rng = np.random.default_rng(15)
    cells = Cells.from_directions(random_directions(rng, 4000), random_directions(rng, 4000))
    for alpha in (1e-4, 3e-3, 0.05, 0.3, 0.9, 1.0):
        p = f64(alpha=alpha, gamma=2.0)
        d_gtr, _ = GTR.reference(cells, **p, **GTR.consts(**p))
        d_ggx, _ = REGISTRY["ndf"]["ggx"].reference(cells, alpha=p["alpha"])
        ok = d_ggx > 1e-300
        assert np.max(np.abs(d_gtr[ok] / d_ggx[ok] - 1)) < 1e-12, alpha
        for hc in ("", "_hc"):
            g_gtr, _ = REGISTRY["shadowing"][f"smith_gtr{hc}"].reference(cells, **p)
            g_ggx, _ = REGISTRY["shadowing"][f"smith_ggx{hc}"].reference(cells, alpha=p["alpha"])
            assert np.max(np.abs(g_gtr / g_ggx - 1)) < 1e-12, (alpha, hc)


def test_gtr_lobe_at_gamma_2_is_the_ggx_lobe():
    rng = np.random.default_rng(2)
    cells = Cells.from_directions(random_directions(rng, 2000), random_directions(rng, 2000))
    gtr, ggx = Model("diffuse+gtr:smith:schlick"), Model("diffuse+ggx:smith:schlick")
    v = ggx.defaults()
    v[ggx.names.index("ct.alpha")] = 0.07
    w = np.array([v[ggx.names.index(n)] if n != "ct.gamma" else 2.0 for n in gtr.names])
    p1, p2 = gtr.reference(cells, w, jacobian=False), ggx.reference(cells, v, jacobian=False)
    assert np.max(np.abs(p1 / p2 - 1)) < 1e-12


# --- normalisation: int D cos theta dw = 1 -----------------------------------------------------------
def normalisation(term, **p):
    """2 pi int D cos sin dtheta, on x = ln tan theta (sin cos dtheta = t^2 / (1 + t^2)^2 dx)."""
    x, w = panels(peak_log_slope(term, p) - 25.0, 16.0)
    t = np.exp(x)
    return 2 * np.pi * np.sum(w * ndf(term, t, **p) * t * t / (1 + t * t) ** 2)


@pytest.mark.parametrize("alpha", [1e-4, 1e-3, 0.005, 0.03, 0.1, 0.3, 0.7, 1.0])
def test_gtr_is_normalised(alpha):
    for gamma in np.linspace(1.05, 4.0, 12):
        assert abs(normalisation(GTR, alpha=alpha, gamma=gamma) - 1) < 1e-6, gamma


@pytest.mark.parametrize("B", [0.1, 1.0, 30.0, 1e3, 1e5, 1e8])
def test_abc_is_normalised(B):
    for C in (*np.linspace(0.25, 8.0, 11), 1.0, 2.0, 1.0 + 1e-9, 2.0 - 1e-9):
        assert abs(normalisation(ABC, B=B, C=C) - 1) < 1e-6, C


def test_host_constants_are_continuous_where_the_closed_forms_are_singular():
    """ABC's normalisation at C = 1, 2 (logarithmic cases), GTR's at alpha = 1 (uniform D)."""
    for C in (1.0, 2.0):
        n0 = ABC.consts(**f64(B=50.0, C=C))
        for dc in (-1e-7, 1e-7):
            n1 = ABC.consts(**f64(B=50.0, C=C + dc))
            for k in n0:
                assert abs(n1[k] - n0[k]) <= 1e-5 * abs(n0[k]), (C, k)
    k = GTR.consts(**f64(alpha=1.0, gamma=1.7))
    assert abs(k["K"] * np.pi - 1) < 1e-15 and np.isfinite(list(k.values())).all()


# --- reciprocity --------------------------------------------------------------------------------------
@pytest.mark.parametrize("spec", ["diffuse+gtr:smith:schlick", "diffuse+gtr:smith-hc:conductor",
                                  "diffuse+abc:smith:schlick", "abc:smith-hc:dielectric"])
def test_lobe_is_reciprocal(spec):
    rng = np.random.default_rng(7)
    model = Model(spec)
    wi, wo = random_directions(rng, 3000), random_directions(rng, 3000)
    for _ in range(4):
        v = model.from_x(model.x_lo + rng.random(model.n_free) * (model.x_hi - model.x_lo))
        a = model.reference(Cells.from_directions(wi, wo), v, jacobian=False)
        b = model.reference(Cells.from_directions(wo, wi), v, jacobian=False)
        assert np.all(np.isfinite(a))
        assert np.max(np.abs(a - b) / np.maximum(np.abs(a), 1e-300)) < 1e-12


# --- the weak white furnace: G1(o) int max(0, o.m) D(m) dm / cos theta_o = 1 -----------------------
def furnace(term, shadowing, theta_o_deg, **p):
    """G1 times the visible projected area over cos theta_o, the phi integral in closed form
    (int max(0, a cos phi + b) dphi = 2 pi b for b >= a, else 2 (sqrt(a^2 - b^2) + b (pi - arccos(b/a)))),
    theta on x = ln tan theta (sin dtheta = t^2 / (1 + t^2)^(3/2) dx), split where b = a (tan theta =
    1 / tan theta_o) with x = x0 + s^2 beyond it (the square-root onset made smooth)."""
    to = np.radians(theta_o_deg)
    x0 = -np.log(np.tan(to))
    lo = min(peak_log_slope(term, p), x0) - 25.0
    xl, wl = panels(lo, x0)
    s, ws = panels(0.0, np.sqrt(16.0 - x0))
    x, w = np.concatenate([xl, x0 + s * s]), np.concatenate([wl, 2 * s * ws])
    t = np.exp(x)
    st, ct = t / np.sqrt(1 + t * t), 1 / np.sqrt(1 + t * t)
    a, b = np.sin(to) * st, np.cos(to) * ct
    front = np.where(b >= a, 2 * np.pi * b, 2 * (np.sqrt(np.maximum(a * a - b * b, 0))
                                                  + b * (np.pi - np.arccos(np.clip(b / np.maximum(a, 1e-300), -1, 1)))))
    visible = np.sum(w * front * ndf(term, t, **p) * t * t / (1 + t * t) ** 1.5) / np.cos(to)
    co = np.array([np.cos(to)])
    one = np.ones(1)
    g1, _ = REGISTRY["shadowing"][shadowing].reference(Cells(0 * one, one, one, one, co), **f64(**p))
    return g1[0] * visible


@pytest.mark.parametrize("alpha", [0.005, 0.05, 0.3, 0.7])
@pytest.mark.parametrize("gamma", [1.05, 1.1, 1.5, 2.5, 4.0])
def test_weak_white_furnace_gtr(alpha, gamma):
    for theta in (10.0, 45.0, 70.0, 80.0):
        for g in ("smith_gtr", "smith_gtr_hc"):      # G(theta_i = 0) is G1(theta_o) for both
            assert abs(furnace(GTR, g, theta, alpha=alpha, gamma=gamma) - 1) < G1_ERROR, (theta, g)


@pytest.mark.parametrize("B", [0.1, 3.0, 100.0, 1e4, 1e7])
@pytest.mark.parametrize("C", [0.25, 0.5, 1.0, 2.0, 3.0, 8.0])
def test_weak_white_furnace_abc(B, C):
    for theta in (10.0, 45.0, 70.0, 80.0):
        assert abs(furnace(ABC, "smith_abc", theta, B=B, C=C) - 1) < G1_ERROR, theta


def test_furnace_integral_is_exact_for_ggx():
    """The furnace quadrature itself, on GGX (closed-form Lambda): 1 to 1e-9."""
    for theta in (10.0, 60.0, 80.0):
        assert abs(furnace(GTR, "smith_ggx", theta, alpha=0.02, gamma=2.0) - 1) < 1e-9


# --- model strings ------------------------------------------------------------------------------------
def test_model_strings():
    m = Model("diffuse+diffraction:abc+gtr:smith:schlick")
    assert m.spec == "diffuse+diffraction:abc:none+gtr:smith:schlick"
    assert "ct.gamma" in m.names and "diffraction.c" in m.names
    ct = m.lobes_with_role("reflection")[0]
    assert ct.shadowing.name == "smith_gtr"
    m = Model("abc:smith:schlick")
    ct = m.lobes[0]
    assert ct.ndf.name == "abc" and ct.shadowing.name == "smith_abc" and {"ct.B", "ct.C"} <= set(m.names)
    assert Model("abc").lobes[0].shadowing.name == "smith_abc"          # smith by default
    assert Model("gtr:smith-hc:none").lobes[0].shadowing.name == "smith_gtr_hc"
    assert Model(Model("abc:smith-hc:conductor").spec).spec == "abc:smith-hc:conductor"


@pytest.mark.parametrize("series, lo, hi", [("smith_gtr", (0.905, 1.05), (1.0, 4.0)),
                                            ("smith_abc", (0.1, 0.25), (1e5, 8.0))])
def test_series_coefficients_kept_are_those_computed_alone(series, lo, hi):
    """A series Lambda's host constants, where its rule gives them (GTR: alpha above its table's
    box, tests/test_series_table.py), are the same whether a parameter vector's coefficients are
    computed now, on their own, or taken from those it kept (repeated rows, several calls, its
    bound passed), in the shape of the inputs."""
    from brdfcl.model.terms.shadowing import smith
    from brdfcl.model.terms.shadowing.smith_abc import LAMBDA_ABC
    from brdfcl.model.terms.shadowing.smith_gtr import LAMBDA_GTR
    lam = {"smith_gtr": LAMBDA_GTR, "smith_abc": LAMBDA_ABC}[series]
    rng = np.random.default_rng(3)
    a, b = rng.uniform(lo[0], hi[0], 40), rng.uniform(lo[1], hi[1], 40)
    a[::5], b[::5] = a[1], b[1]                       # repeated rows within one call

    cos2_b, weights = smith.density_weights(smith.HOST_NODES)
    tan2 = (1 - smith._COS ** 2) / smith._COS ** 2

    def alone(i):
        """One vector's coefficients, its rule summed node by node."""
        at = {lam.inputs[0]: np.float64(a[i]), lam.inputs[1]: np.float64(b[i])}
        def point(u):
            co = np.full(1, 1 / np.sqrt(1 + u))
            return lam.integrand.reference(smith._Nodes(co, co, np.full(1, u)), **at)
        on_nodes = [point(t * c) for t in tan2 for c in cos2_b]

        def coefficients(part):
            rule = np.array([sum(w * part(on_nodes[k * len(cos2_b) + j])[0] for j, w in enumerate(weights))
                             for k in range(len(tan2))])
            return (smith._COS * rule) @ smith._TO_COEF.T
        return coefficients(lambda o: o[0]), {p: coefficients(lambda o, p=p: o[1][p]) for p in lam.inputs}
    lam._memo.clear()
    first = lam.host_consts(**{lam.inputs[0]: a.reshape(8, 5), lam.inputs[1]: b.reshape(8, 5)})
    again = lam.host_consts(**{lam.inputs[0]: a[::-1], lam.inputs[1]: b[::-1]})
    scalar = lam.host_consts(**{lam.inputs[0]: a[7], lam.inputs[1]: b[7]})
    assert first[0]["c0"].shape == (8, 5) and again[0]["c0"].shape == (40,) and scalar[0]["c0"].shape == ()
    for i in (0, 1, 7, 13, 39):
        coef, dcoef = alone(i)
        for k, c in enumerate(lam.host):
            np.testing.assert_allclose(first[0][c].ravel()[i], coef[k], rtol=1e-9, atol=1e-12)
            np.testing.assert_array_equal(again[0][c][39 - i], first[0][c].ravel()[i])
            for p in lam.inputs:
                np.testing.assert_allclose(first[1][c][p].ravel()[i], dcoef[p][k], rtol=1e-9, atol=1e-12)
                np.testing.assert_array_equal(again[1][c][p][39 - i], first[1][c][p].ravel()[i])
    np.testing.assert_array_equal(scalar[0]["c3"], first[0]["c3"].ravel()[7])
    assert len(lam._memo) == len(set(zip(a, b)))
    keep = smith.MEMO
    try:
        smith.MEMO = 16
        many = rng.uniform(lo[0], hi[0], 50), rng.uniform(lo[1], hi[1], 50)
        out = lam.host_consts(**dict(zip(lam.inputs, many)))
        assert len(lam._memo) <= 16 and np.isfinite(out[0]["c0"]).all() and out[0]["c0"].shape == (50,)
    finally:
        smith.MEMO = keep
        lam._memo.clear()
