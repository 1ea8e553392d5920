"""The engine on scattered samples: any number of channels, one geometry per material, materials
with different sample counts in one cell set; kernels against the float64 reference."""
import numpy as np
import pytest

from brdfcl.device.engine import Engine
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.metrics import transform


def _directions(rng, n):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.2
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _reference(model, cells, vals, w, values):
    p, J = model.reference(cells, values)
    gp, dg = transform("log", p * cells.ci)
    r = np.nan_to_num(gp - transform("log", vals * cells.ci)[0])
    return float(np.sum(w * r * r)), 2 * np.einsum("cn,cnk->k", w * r, (dg * cells.ci)[..., None] * J), p


def _check(model, cells, weights, values, real="float", tol=2e-5):
    eng = Engine(model, real=real)
    names = [f"m{i}" for i in range(len(cells))]
    cs = eng.upload_cells(names, cells, weights, values)
    m = model
    V = np.stack([m.defaults(), m.from_x(m.search_x_lo + 0.3 * (m.search_x_hi - m.search_x_lo)),
                  m.from_x(m.search_x_lo + 0.7 * (m.search_x_hi - m.search_x_lo))])
    mats = np.arange(len(V)) % len(cells)
    L, G = eng.grad(cs, V, mats)
    P = eng.predict(cs, V, mats)
    for k, mat in enumerate(mats):
        lr, gr, p = _reference(m, cells[mat], values[mat], weights[mat], V[k])
        assert L[k] == pytest.approx(lr, rel=tol)
        np.testing.assert_allclose(G[k], gr, rtol=tol, atol=tol * np.abs(gr).max())
        np.testing.assert_allclose(P[k][:, :len(cells[mat])], p, rtol=tol, atol=tol * np.abs(p).max())


def test_five_channels_two_materials_of_different_sizes():
    rng = np.random.default_rng(7)
    lambdas = (0.42, 0.48, 0.53, 0.6, 0.68)
    model = Model("diffuse+diffraction+ggx", lambdas=lambdas)
    assert model.n_channels == 5 and "diffuse.rho_530nm" in model.names
    cells, weights, values = [], [], []
    for n in (301, 77):
        c = Cells.from_directions(_directions(rng, n), _directions(rng, n))
        truth = model.reference(c, model.from_x(model.search_x_lo + 0.5 * (model.search_x_hi - model.search_x_lo)),
                                jacobian=False)
        v = truth * (1 + 0.1 * rng.normal(size=truth.shape))
        v[:, :3] = np.nan                                   # missing samples
        cells.append(c)
        weights.append(rng.random(n))
        values.append(v)
    _check(model, cells, weights, values, "float")
    _check(model, cells, weights, values, "double", tol=1e-9)


def test_channel_count_must_match_the_model():
    model = Model("diffuse", lambdas=(0.5, 0.6))
    eng = Engine(model)
    c = Cells.from_directions(_directions(np.random.default_rng(1), 20), _directions(np.random.default_rng(2), 20))
    with pytest.raises(ValueError, match="3 channels, but the model has 2"):
        eng.upload_cells(["x"], [c], [np.ones(20)], [np.ones((3, 20))])


def test_krylon_31_bands(krylon):
    s = krylon
    ok = s.mask(80.0)
    cells = Cells.from_directions(s.wi[ok], s.wo[ok])
    model = Model("diffuse+diffraction", lambdas=tuple(s.wavelengths))
    assert model.n_channels == 31
    _check(model, [cells], [s.weights_within(80.0)[ok]], [s.values[ok].T], "float")
