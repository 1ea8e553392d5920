"""Fitting scattered spectral samples: known parameters come back, and the real Cornell
measurement fits with every band."""
import numpy as np
import pytest

from brdfcl.data.samples import Channel, make_samples
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.optim.fit import FitOptions, fit_samples

LAMBDAS = (0.42, 0.5, 0.58, 0.66)


def _synthetic(truth, n, seed):
    rng = np.random.default_rng(seed)
    ti, to = np.arccos(rng.uniform(0.25, 1.0, n)), np.arccos(rng.uniform(0.25, 1.0, n))
    pi, po = np.zeros(n), rng.uniform(-np.pi, np.pi, n)
    ch = [Channel(f"{x * 1000:g}nm", x) for x in LAMBDAS]
    flat = make_samples(None, ti, pi, to, po, np.ones((n, len(ch))), ch, name="x")
    model = Model("diffuse+ggx", lambdas=LAMBDAS)
    v = model.reference(Cells.from_directions(flat.wi, flat.wo), np.array([truth[k] for k in model.names]),
                        jacobian=False)
    return make_samples(None, ti, pi, to, po, v.T, ch, name=f"synth{seed}")


def test_known_parameters_come_back_from_two_materials_of_different_sizes():
    model = Model("diffuse+ggx", lambdas=LAMBDAS)
    truths = []
    for alpha, rd in ((0.08, 0.2), (0.3, 0.05)):
        v = model.as_dict(model.defaults())
        v.update({f"diffuse.rho_{c}": rd * (1 + 0.2 * i) for i, c in enumerate(model.channels)})
        v.update({f"ct.rho_{c}": 0.6 for c in model.channels})
        v.update({f"ct.F0_{c}": 0.1 for c in model.channels})
        v["ct.alpha"] = alpha
        truths.append(v)
    samples = [_synthetic(truths[0], 900, 1), _synthetic(truths[1], 400, 2)]
    results = fit_samples(samples, FitOptions(model="diffuse+ggx"))
    assert [r.name for r in results] == ["synth1", "synth2"]
    for r, truth in zip(results, truths):
        assert r.success and r.errors["rel_rmse"] < 1e-3, (r.name, r.errors)
        assert r.params["ct.alpha"] == pytest.approx(truth["ct.alpha"], rel=1e-3)
        for c in model.channels:
            assert r.params[f"diffuse.rho_{c}"] == pytest.approx(truth[f"diffuse.rho_{c}"], rel=1e-3)


def test_samples_with_other_bands_are_refused():
    a = _synthetic(Model("diffuse+ggx", lambdas=LAMBDAS).as_dict(Model("diffuse+ggx", lambdas=LAMBDAS).defaults()),
                   50, 3)
    b = make_samples(None, a.theta_i, a.phi_i, a.theta_o, a.phi_o, a.values[:, :3],
                     [Channel("R", 0.645), Channel("G", 0.526), Channel("B", 0.444)], name="rgb")
    with pytest.raises(ValueError, match="different sets of wavelengths"):
        fit_samples([a, b])


def test_krylon_fits_in_every_band(krylon):
    r = fit_samples([krylon], FitOptions(model="diffuse+diffraction+ggx"))[0]
    assert r.success and len([k for k in r.params if k.startswith("diffuse.rho_")]) == 31
    assert r.errors["rel_rmse"] < 0.3
    assert r.uncertainty is not None and r.albedo is not None


def test_a_31_band_material_with_diffraction_comes_back_to_one_percent():
    """31 bands (400 to 700 nm) of the three-lobe model, no noise: every parameter of every band
    is recovered to 1%."""
    lambdas = tuple(np.round(np.linspace(0.4, 0.7, 31), 3))
    model = Model("diffuse+diffraction+ggx", lambdas=lambdas)
    truth = model.as_dict(model.defaults())
    for i, c in enumerate(model.channels):
        x = i / 30
        truth.update({f"diffuse.rho_{c}": 0.02 + 0.1 * x, f"diffraction.rho_{c}": 0.04 * (1 - 0.5 * x),
                      f"ct.rho_{c}": 0.5, f"ct.F0_{c}": 0.3 + 0.2 * x})
    truth.update({"diffraction.a": 1.5, "ct.alpha": 0.06})
    rng = np.random.default_rng(5)
    n = 2000
    ti, to = np.arccos(rng.uniform(0.2, 0.99, n)), np.arccos(rng.uniform(0.2, 0.99, n))
    pi, po = np.zeros(n), rng.uniform(-np.pi, np.pi, n)
    ch = [Channel(f"{x * 1000:g}nm", x) for x in lambdas]
    flat = make_samples(None, ti, pi, to, po, np.ones((n, 31)), ch, name="s31")
    v = model.reference(Cells.from_directions(flat.wi, flat.wo), model.only_lobes(truth, None), jacobian=False)
    (r,) = fit_samples([make_samples(None, ti, pi, to, po, v.T, ch, name="s31")],
                       FitOptions(model="diffuse+diffraction+ggx"))
    assert r.success and r.errors["rel_rmse"] < 1e-3, r.errors
    assert len(truth) == 4 * 31 + 2
    for k, want in truth.items():
        assert r.params[k] == pytest.approx(want, rel=0.01), k
