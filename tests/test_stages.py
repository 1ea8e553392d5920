"""The fit's stages called on their own (brdfcl.optim.search, .objective, .spaces), and the
parameter spaces' maps (numpy only)."""
import numpy as np
import pytest

from brdfcl.data.merl import read_merl
from brdfcl.model.compose import Model
from brdfcl.optim.fit import FitOptions, Fitter
from brdfcl.optim.result import StageResult
from brdfcl.optim.search import global_search, pick_starts
from brdfcl.optim.spaces import Spaces

MATERIAL = "synth-smooth-metal"        # has a diffraction lobe: the peak constraint applies


def test_spaces_round_trip_and_chain_rule():
    m = Model()
    sp = Spaces(m)
    rng = np.random.default_rng(5)
    lo, hi = sp.x_bounds
    x = lo + rng.uniform(0.1, 0.9, size=(4, m.n_free)) * (hi - lo)     # inside: values are clipped
    np.testing.assert_allclose(sp.from_y(sp.to_y(x)), x, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(sp.to_x(sp.values(x)), x, rtol=1e-13, atol=1e-13)
    y = sp.to_y(x)
    np.testing.assert_array_equal(y[:, sp.linear], np.exp(x[:, sp.linear]))      # amplitudes natural
    np.testing.assert_array_equal(y[:, ~sp.linear], x[:, ~sp.linear])            # shapes stay in x
    v = sp.values(x)
    e = 1e-6
    for k in range(m.n_free):                     # d v / d y by central differences, column by column
        dy = np.zeros(m.n_free)
        dy[k] = e * (abs(y[0, k]) or 1.0)
        fd = (sp.values(sp.from_y(y[:1] + dy)) - sp.values(sp.from_y(y[:1] - dy)))[0, m.free_index] / (2 * dy[k])
        assert fd[k] == pytest.approx(sp.dv_dy(v)[0, k], rel=1e-6), m.names[m.free_index[k]]


@pytest.fixture(scope="module")
def constrained(demo_db):
    f = Fitter(FitOptions(ct_peak=True, n_candidates=32, n_starts=2))
    b = f.load([read_merl(demo_db / f"{MATERIAL}.binary")])
    return f, b


def test_global_search_and_pick_starts_alone_with_the_peak_constraint(constrained):
    """Each stage called on its own, the constraint on (they once needed state only fit() set):
    scipy-style results, the penalty in their losses, and the start the pipeline itself takes."""
    f, b = constrained
    t, names = b.targets, b.names
    found = global_search(f.objective, t.coarse, names=names, options=f.opts)
    assert isinstance(found, StageResult)
    assert found.x.shape == (1 + f.opts.n_starts, f.model.n_free) and (found.mat == 0).all()
    assert np.isfinite(found.fun).all() and found.nfev[0] >= 1 + f.opts.n_candidates
    start = pick_starts(f.objective, t.full, found, n_materials=1)
    assert start.x.shape == (1, f.model.n_free) and start.success.all() and np.isfinite(start.fun).all()
    assert start.fun[0] <= f.objective.loss(t.full, found.x, found.mat).min()
    # the penalty is part of both stages' losses
    free = f.objective.loss(t.full, start.x, [0], penalty=False)
    v = f.objective.spaces.values(start.x)
    assert f.objective.loss(t.full, start.x, [0])[0] == free[0] + f.objective.peak_order.loss(v, t.full.scale)[0]
    # the pipeline ranks the starts on the preview cells and starts its local stage from the one
    # picked there: its first history entry, the preview's estimate of the full table's error
    assert t.preview is not None
    ranked = pick_starts(f.objective, t.preview, found, n_materials=1)
    (res,) = f.fit_loaded(b)
    assert res.history[0][1] == "global"
    assert res.history[0][2] == float(np.sqrt(f.objective.loss(t.preview, ranked.x, np.arange(1))[0] / t.full.scale[0]))
    assert res.history[0][2] == pytest.approx(float(np.sqrt(ranked.fun[0] / t.full.scale[0])), rel=1e-12)


def test_objective_forms_agree(constrained):
    """Loss, gradient (x) and Gauss-Newton (y) forms of the penalised loss give the same loss, and
    the penalty's Hessian is J^T J of its residuals."""
    f, b = constrained
    t = b.targets
    obj, sp = f.objective, f.objective.spaces
    x = sp.default_x(1)
    v = sp.values(x)
    v[0, f.model.names.index("diffraction.rho_r")] *= 1e3          # violates the constraint
    x = sp.to_x(v)
    L = obj.loss(t.full, x, [0])
    Lg, g = obj.loss_grad(t.full, x, [0])
    Lj, jtr, jtj = obj.jtj(t.full, sp.to_y(x), np.array([0]))
    assert Lg[0] == L[0] and Lj[0] == pytest.approx(L[0], rel=1e-6)
    assert obj.peak_order.loss(v, t.full.scale)[0] > 0
    _, J = obj.peak_order.residual(v, t.full.scale)
    np.testing.assert_array_equal(obj.penalty_hessian(v, t.full.scale), np.einsum("nci,ncj->nij", J, J))
    # the gradient in x is 2 J^T r in y times dy/dx
    dy_dx = np.where(sp.linear, sp.to_y(x), 1.0)
    np.testing.assert_allclose(g, 2 * jtr * dy_dx, rtol=1e-4, atol=1e-6 * np.abs(g).max())
