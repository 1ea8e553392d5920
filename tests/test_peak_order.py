"""The peak constraint: Cook-Torrance carries the specular peak (brdfcl.optim.peak_order)."""
import numpy as np

from brdfcl.analysis.analyze import peak_share
from brdfcl.data.merl import read_merl
from brdfcl.model.compose import Model
from brdfcl.optim.fit import FitOptions, Fitter
from brdfcl.optim.peak_order import PeakOrder


def assert_residual_jacobian(po, m, V, scale, J):
    """PeakOrder.residual's Jacobian J against central differences, column by column."""
    for j, col in enumerate(m.free_index):
        e = 1e-6 * max(abs(V[0, col]), 1e-3)
        Vp, Vm = V.copy(), V.copy()
        Vp[:, col] += e
        Vm[:, col] -= e
        fd = (po.residual(Vp, scale)[0] - po.residual(Vm, scale)[0]) / (2 * e)
        assert np.allclose(fd, J[:, :, j], rtol=1e-5, atol=1e-7 * np.abs(J).max()), m.names[col]

def test_residual_jacobian_matches_finite_differences():
    m = Model()
    po = PeakOrder.for_model(m)
    rng = np.random.default_rng(1)
    V = np.tile(m.defaults(), (6, 1))
    V[:, 3:6] *= rng.uniform(1, 100, (6, 3))
    V[:, m.names.index("diffraction.a")] = rng.uniform(0.2, 3, 6)
    scale = rng.uniform(0.5, 2, 6)
    r, J = po.residual(V, scale)
    assert (r > 0).sum() >= 6                        # the test points violate the constraint
    assert_residual_jacobian(po, m, V, scale, J)


def test_only_models_with_both_lobes_are_constrained():
    assert PeakOrder.for_model(Model("diffuse+ggx")) is None
    assert PeakOrder.for_model(Model("diffuse+diffraction:hp")) is None
    assert PeakOrder.for_model(Model("diffraction:abc+beckmann:vcavity:dielectric")) is not None


def test_fit_gives_the_peak_to_cook_torrance():
    """gold-metallic-paint (proxy): a free fit puts most of the peak on a narrow diffraction lobe;
    with the constraint CT carries at least as much in every channel."""
    from tests.conftest import proxy_files
    (path,) = proxy_files(["gold-metallic-paint"])
    out = {}
    for flag in (False, True):
        f = Fitter(FitOptions(ct_peak=flag))
        (r,) = f.fit([read_merl(path)])
        assert r.success, r.status
        out[flag] = r
    m = Model(out[True].model)
    po = PeakOrder.for_model(m)
    excess = {k: po.excess(np.array([r.params[n] for n in m.names]))[0] for k, r in out.items()}
    assert excess[False].max() > 0.1 and peak_share(m.spec, out[False].params) > 0.6
    assert excess[True].max() < 0.02 and peak_share(m.spec, out[True].params) < 0.51
    assert out[True].errors["rmse_log"] < 1.5 * out[False].errors["rmse_log"]
