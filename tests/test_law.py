"""The wavelength law's model comparison (brdfcl.analysis.law) and the calibration's classes that
change colour with angle by other means (brdfcl.analysis.calibration), without fitting."""
from types import SimpleNamespace

import numpy as np
import pytest

from brdfcl.analysis import calibration as cal
from brdfcl.analysis.gradient import MAX_TD_DEG, WIDE_TH_DEG
from brdfcl.analysis.law import GREY, NO_TEST, LawTest, grey_lambdas, law_test, wide_cells, wide_error
from brdfcl.data.geometry import table_geometry
from brdfcl.model.compose import Model

SPEC = "diffuse+diffraction+ggx"


def _fit(model, values, ok=True):
    return SimpleNamespace(params=model.as_dict(values), success=ok, errors={"rmse_log": 0.01})


def test_law_ratio_and_grey_channels():
    assert LawTest(0.01, 0.02, 5).ratio == pytest.approx(0.5)
    assert np.isnan(NO_TEST.ratio) and LawTest(0.01, 0.0, 5).ratio == np.inf and np.isnan(LawTest(0, 0, 5).ratio)
    assert LawTest(0.01, 0.02, 5, 0.03, 0.01).colour_ratio == pytest.approx(3.0)
    assert np.isnan(NO_TEST.colour_ratio) and np.isnan(LawTest(0.01, 0.02, 5).colour_ratio)
    grey = grey_lambdas((0.4, 0.5, 0.6, 0.7))
    assert len(set(grey)) == 4 and max(grey) / min(grey) - 1 < 1e-4 and grey[0] == 0.6


def test_wide_cells_are_the_gradient_tests_region():
    cells, idx, w = wide_cells()
    g = table_geometry()
    assert idx.size > 100_000 and np.all(w > 0)
    assert np.degrees(g.theta_h[idx]).min() >= WIDE_TH_DEG - 1e-9
    assert np.degrees(g.theta_d[idx]).max() <= MAX_TD_DEG + 1e-9


def test_the_law_prefers_the_wavelength_a_halo_was_made_with():
    """Values made by the full model with each channel's wavelength: its own fit has error 0 there,
    the same parameters at one wavelength do not, so the ratio is 0; made at one wavelength, the
    other way round.  A failed or missing rival gives no test."""
    model = Model(SPEC)
    v = model.defaults()
    v[model.names.index("diffraction.a")] = 2.0
    cells, idx, _ = wide_cells()
    made = model.reference(cells, v, jacobian=False)
    grey = Model(SPEC, lambdas=grey_lambdas(model.lambdas))
    made_grey = grey.reference(cells, v, jacobian=False)
    fits = {"full": _fit(model, v), GREY: _fit(grey, v)}
    t = law_test(fits, SPEC, model.lambdas, cells, made)
    assert t.error == pytest.approx(0, abs=1e-12) and t.error_grey > 1e-3 and t.ratio < 1e-6
    assert t.colour == pytest.approx(0, abs=1e-12) and t.colour_grey > 1e-3 and t.colour_ratio < 1e-6
    assert t.n_cells == idx.size
    assert law_test(fits, SPEC, model.lambdas, cells, made_grey).ratio == np.inf
    assert law_test({"full": fits["full"]}, SPEC, model.lambdas, cells, made) is NO_TEST
    assert law_test({**fits, GREY: _fit(grey, v, ok=False)}, SPEC, model.lambdas, cells, made) is NO_TEST
    e, n, c = wide_error(model, fits["full"].params, cells, np.full_like(made, np.nan))
    assert np.isnan(e) and n == 0 and np.isnan(c)


def test_the_colour_ratio_ignores_a_misfit_the_channels_share():
    """A misfit common to every channel (the data x a factor that varies over the cells) changes
    E of both fits but not their colour errors C: the colour ratio of a halo stays 0."""
    model = Model(SPEC)
    v = model.defaults()
    v[model.names.index("diffraction.a")] = 2.0
    cells, idx, _ = wide_cells()
    made = model.reference(cells, v, jacobian=False)
    grey = Model(SPEC, lambdas=grey_lambdas(model.lambdas))
    fits = {"full": _fit(model, v), GREY: _fit(grey, v)}
    shared = made * np.exp(np.random.default_rng(0).normal(0, 0.5, idx.size))
    t0, t = law_test(fits, SPEC, model.lambdas, cells, made), law_test(fits, SPEC, model.lambdas, cells, shared)
    assert t.error > 0.3 and t.error_grey > 0.3 and 0.9 < t.ratio <= 1.0
    assert t.colour == pytest.approx(t0.colour, abs=1e-12) and t.colour_grey == pytest.approx(t0.colour_grey, rel=1e-9)
    assert t.colour_ratio < 1e-6
    one = law_test({"full": _fit(Model(SPEC, lambdas=(0.55,)), v), GREY: _fit(Model(SPEC, lambdas=(0.55,)), v)},
                   SPEC, (0.55,), cells, made[1:2])
    assert np.isfinite(one.ratio) and np.isnan(one.colour_ratio)          # one channel: no colour


def test_film_reflectance_is_airy():
    th = np.radians(np.array([0.0, 30.0, 60.0]))
    bare = cal.film_reflectance(th[:1], (0.55,), (1.5, 0.0, 1.5))      # no film: the substrate's Fresnel
    assert bare[0, 0] == pytest.approx(0.04, rel=1e-9)
    quarter = cal.film_reflectance(th[:1], (0.55,), (np.sqrt(1.5), 0.55 / (4 * np.sqrt(1.5)), 1.5))
    assert quarter[0, 0] == pytest.approx(0.0, abs=1e-12)               # a quarter-wave coating
    r = cal.film_reflectance(th, (0.45, 0.55, 0.65), (2.2, 0.3, 1.5))
    assert r.shape == (3, 3) and np.all((r >= 0) & (r <= 1))
    assert np.ptp(r[:, 0]) > 0.05                                       # colour at normal incidence...
    assert not np.allclose(r[:, 0] / r[:, 0].mean(), r[:, 2] / r[:, 2].mean(), rtol=0.05)   # ...shifts with angle


@pytest.mark.parametrize("cls", cal.COLOUR_CLASSES)
def test_colour_classes_have_no_diffraction_and_vary_by_channel(cls):
    case = cal._draw(cls, 0.0, np.random.default_rng(1), f"{cls}-0")
    assert not case.has_diffraction and case.cls == cls
    clean, measured = cal.synthesize(case, cal.slice_index())
    ok = np.isfinite(clean).all(axis=0) & (clean > 0).all(axis=0)
    assert ok.sum() > 1000 and np.isfinite(measured[:, ok]).mean() > 0.8      # cells beyond 86 deg are missing
    chroma = np.log(clean[0, ok] / clean[2, ok])
    assert np.ptp(chroma) > 0.05            # the red/blue balance changes across the table
    assert (case.film is not None) == (cls == "thin-film")
