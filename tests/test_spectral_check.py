"""The wavelength check on spectral samples, on synthetic samples with a known answer."""
import numpy as np

from brdfcl.analysis.spectral import lambda_exponent, spectral_check
from brdfcl.data.samples import Channel, make_samples
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells

LAMBDAS = tuple(np.round(np.linspace(0.40, 0.70, 13), 3))
CHANNELS = [Channel(f"{x * 1000:g}nm", x) for x in LAMBDAS]


def _angles(n=2500, seed=0):
    rng = np.random.default_rng(seed)
    return (np.arccos(rng.uniform(0.2, 0.98, n)), np.zeros(n), np.arccos(rng.uniform(0.2, 0.98, n)),
            rng.uniform(-np.pi, np.pi, n))


def _samples(model, values, noise=0.02, seed=0):
    """Samples of ``model`` at ``values`` (by slot order) with multiplicative noise, labelled with
    the bands of LAMBDAS whatever wavelengths the model used to make them."""
    ti, pi, to, po = _angles(seed=seed)
    flat = make_samples(None, ti, pi, to, po, np.ones((ti.size, len(LAMBDAS))), CHANNELS, name="synth")
    p = model.reference(Cells.from_directions(flat.wi, flat.wo), values, jacobian=False)
    v = p.T * np.exp(noise * np.random.default_rng(seed + 1).normal(size=p.T.shape))
    return make_samples(None, ti, pi, to, po, v, CHANNELS, name="synth")


def _params(model, n_exp):
    """Values (by slot order) with a diffraction amplitude rho_c lambda_c^-4 = 0.05 lambda_c^-n."""
    v = model.as_dict(model.defaults())
    for c, lam in zip(model.channels, LAMBDAS):
        v[f"diffuse.rho_{c}"] = 0.02
        v[f"diffraction.rho_{c}"] = 0.05 * lam ** (4 - n_exp)
        v[f"ct.rho_{c}"] = 0.3
    v["diffraction.a"], v["ct.alpha"] = 2.0, 0.05
    return v


def test_exponent_from_the_band_amplitudes():
    model = Model("diffuse+diffraction+ggx", lambdas=LAMBDAS)
    for n in (4.0, 2.0, 0.0):
        got, se = lambda_exponent(model, _params(model, n))
        assert abs(got - n) < 1e-9 and se < 1e-6


def test_diffraction_collapses_against_f():
    model = Model("diffuse+diffraction+ggx", lambdas=LAMBDAS)
    params = _params(model, 4.0)
    chk = spectral_check(_samples(model, np.array(list(params.values()))), model, params)
    assert chk is not None and chk.n_wide > 1000
    assert chk.ratio < 0.5 and chk.consistent is True
    assert abs(chk.exponent - 4.0) < 1e-6


def test_scattering_without_the_wavelength_collapses_against_f0():
    """Wide-angle scattering made by one wavelength (0.55 um) in every band: the data collapse
    against f0, not against f, and the check says so decisively."""
    grey = Model("diffuse+diffraction+ggx", lambdas=tuple(0.55 + 1e-4 * i for i in range(len(LAMBDAS))))
    model = Model("diffuse+diffraction+ggx", lambdas=LAMBDAS)
    params = _params(model, 4.0)
    made = np.array(list(_params(grey, 4.0).values()))
    chk = spectral_check(_samples(grey, made), model, params)
    assert chk.ratio > 1.5 and chk.consistent is False
