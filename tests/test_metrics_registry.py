"""Adding a metric is one entry in brdfcl.model.metrics.IMPLEMENTED_METRICS: registered at test time,
a new metric is fitted by the generated kernels and reported by them, matching the float64
reference, with no other file edited."""
import numpy as np
import pytest

from brdfcl.data.geometry import table_geometry
from brdfcl.data.merl import read_merl
from brdfcl.device.engine import Engine, select_cells
from brdfcl.model import metrics
from brdfcl.model.metrics import IMPLEMENTED_METRICS, METRICS, Metric, check_metric, errors, loss_grad, transform

ASINH = Metric("asinh", g=np.arcsinh, dg=lambda x, g: 1 / np.sqrt(1 + x * x),
               c_g="asinh({x})", c_dg="rsqrt(1 + {x} * {x})",
               doc="g(x) = asinh(x), linear near 0 and logarithmic for large x")


@pytest.fixture
def asinh(monkeypatch):
    monkeypatch.setitem(IMPLEMENTED_METRICS, "asinh", ASINH)
    return "asinh"


def test_builtins_are_registered():
    assert tuple(METRICS) == ("l2", "log", "cbrt") and METRICS == ("l2", "log", "cbrt")
    x = np.array([0.0, 0.5, 30.0])
    for name, (g, dg) in {"l2": (x, np.ones(3)), "log": (np.log1p(x), 1 / (1 + x)),
                          "cbrt": (np.cbrt(x + metrics.CBRT_EPS), (x + metrics.CBRT_EPS) ** (-2 / 3) / 3)}.items():
        got = transform(name, x)
        np.testing.assert_allclose(got[0], g, rtol=1e-14)
        np.testing.assert_allclose(got[1], dg, rtol=1e-12)
    with pytest.raises(ValueError, match="valid: l2, log, cbrt"):
        check_metric("asinh")


def test_registered_metric_is_everywhere(asinh):
    from brdfcl.app.cli import build_parser
    assert METRICS[-1] == asinh and asinh in METRICS and check_metric(asinh) == asinh
    x = np.linspace(0, 50, 7)
    g, dg = transform(asinh, x)
    h = 1e-6
    np.testing.assert_allclose(dg, (np.arcsinh(x + h) - np.arcsinh(x - h)) / (2 * h), rtol=1e-7)
    assert build_parser().parse_args(["fit-all", "db", "--out", "o", "--metric", asinh]).metric == asinh


def test_kernels_compute_a_registered_metric(asinh, proxy_pair):
    tables = [read_merl(p) for p in proxy_pair]
    spec = "diffuse+diffraction:abc:conductor+ggx:smith:schlick"
    eng = Engine(spec, real="double", metric=asinh)          # the engine's self-test passes too
    assert "asinh(x)" in eng.source and "rsqrt(1 + x * x)" in eng.source
    idx = select_cells(80)[::1500][:300]
    cs = eng.cellset(tables, idx)
    cells = cs.cells()
    w = table_geometry().weight[idx]
    m = eng.model
    rng = np.random.default_rng(13)
    V = m.from_x(m.x_lo + rng.random((3, m.n_free)) * (m.x_hi - m.x_lo))
    mats = np.arange(len(V)) % 2
    L, G = eng.grad(cs, V, mats)
    E = eng.errors(cs, V, mats)
    for e in range(len(V)):
        meas = tables[mats[e]].brdf()[:, idx]
        lr, gr = loss_grad(m, cells, meas, w, cells.ci, V[e], metric=asinh)
        assert L[e] == pytest.approx(lr, rel=1e-9)
        np.testing.assert_allclose(G[e], gr, rtol=1e-9, atol=1e-9 * np.abs(gr).max())
        p = m.reference(cells, V[e], jacobian=False)
        ref = errors(p, meas, w, cells.ci)
        assert set(E) == set(ref) == {"rmse_l2", "rmse_log", "rmse_cbrt", "rmse_asinh", "rel_rmse"}
        for k, v in ref.items():
            assert E[k][e] == pytest.approx(v, rel=1e-9), k
