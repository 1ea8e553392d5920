import numpy as np
import pytest

from brdfcl.data.geometry import (
    DEFAULT_CUTOFF_DEG,
    bin_centres,
    cells_geometry,
    directions,
    grid_directions,
    table_geometry,
)


def test_directions_are_consistent():
    g = table_geometry()
    for w in (g.wi, g.wo):
        np.testing.assert_allclose(np.linalg.norm(w, axis=1), 1.0, atol=1e-12)
    h = g.wi + g.wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    np.testing.assert_allclose(h[:, 2], np.cos(g.theta_h), atol=1e-9)
    np.testing.assert_allclose(np.sum(g.wi * h, axis=1), np.cos(g.theta_d), atol=1e-9)


def test_bins_follow_merl_index_formulas():
    th, td, pd = bin_centres()
    np.testing.assert_array_equal(np.floor(90 * np.sqrt(th / (np.pi / 2))).astype(int), np.arange(90))
    np.testing.assert_array_equal(np.floor(td / (np.pi / 2) * 90).astype(int), np.arange(90))
    np.testing.assert_array_equal(np.floor(pd / np.pi * 180).astype(int), np.arange(180))


@pytest.mark.parametrize("f, exact", [
    (lambda ci, co: np.ones_like(ci), 4 * np.pi ** 2),               # measure of hemisphere pairs
    (lambda ci, co: ci * co, np.pi ** 2),                            # cosine-weighted pairs
    (lambda ci, co: ci ** 2, 4 * np.pi ** 2 / 3),                    # int cos^2 = 2 pi / 3 times 2 pi
])
def test_weights_integrate_known_functions(f, exact):
    g = table_geometry()
    m = g.above_horizon
    total = np.sum(g.weight[m] * f(g.cos_i[m], g.cos_o[m]))
    assert total == pytest.approx(exact, rel=0.01)


def test_cutoff_mask():
    g = table_geometry()
    m = g.mask(DEFAULT_CUTOFF_DEG)
    c = np.cos(np.radians(DEFAULT_CUTOFF_DEG))
    assert m.sum() < g.above_horizon.sum()
    assert (g.cos_i[m] > c).all() and (g.cos_o[m] > c).all()
    assert (g.mask(None) == g.above_horizon).all()
    with pytest.raises(ValueError):
        g.mask(-5)


def test_table_directions_are_the_general_formula():
    th, td, pd = bin_centres()
    th, td, pd = th[::7], td[::5], pd[::9]
    TH, TD, PD = (a.ravel() for a in np.meshgrid(th, td, pd, indexing="ij"))
    for a, b in zip(grid_directions(th, td, pd), directions(TH, TD, PD)):
        assert np.max(np.abs(a - b)) < 1e-15


def test_cells_geometry_is_the_tables_at_those_cells():
    g = table_geometry()
    index = np.random.default_rng(3).integers(0, g.weight.size, 2000)
    some = cells_geometry(index)
    for name in ("theta_h", "theta_d", "phi_d", "weight"):
        np.testing.assert_array_equal(getattr(some, name), getattr(g, name)[index])
    np.testing.assert_allclose(some.wi, g.wi[index], atol=1e-15)
    np.testing.assert_allclose(some.wo, g.wo[index], atol=1e-15)
    np.testing.assert_array_equal(some.mask(), g.mask()[index])
