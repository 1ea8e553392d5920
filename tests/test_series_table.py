"""The tabulated coefficients of a series Lambda (brdfcl.model.terms.shadowing.series_table)
against the host's rule they stand for: G1 within MAX_G1_ERROR over the box, derivatives that
are the interpolant's own, the rule outside the box, GGX exactly on its node line."""
import numpy as np
import pytest

from brdfcl.model.terms.shadowing import smith
from brdfcl.model.terms.shadowing.series_table import MAX_G1_ERROR, Box, CoefficientTable
from brdfcl.model.terms.shadowing.smith_gtr import LAMBDA_GTR

THETA = np.radians(np.arange(1.0, 80.5, 1.0))          # the fits' range of theta_o


def _series(coef):
    """S(cos theta) / cos theta (m, len(THETA)) of x^k coefficients (m, K)."""
    c = np.cos(THETA)
    x = (c - smith._COS_LO) * 2 / (1 - smith._COS_LO) - 1
    return coef @ (x[None, :] ** np.arange(smith.SERIES_TERMS)[:, None]) / c


def _box_rows(box, m, seed):
    rng = np.random.default_rng(seed)
    a = np.exp(rng.uniform(np.log(box.lo[0]), np.log(box.hi[0]), m))
    b = rng.uniform(box.lo[1], box.hi[1], m)
    return np.stack([a, b], axis=1)


def test_gtr_table_is_within_its_bound_of_the_rule_over_the_box():
    lam = LAMBDA_GTR
    (a0, b0), (a1, b1) = lam.box.lo, lam.box.hi
    rows = np.concatenate([_box_rows(lam.box, 3000, 1), [[a0, b0], [a1, b1], [a0, b1], [a1, b0]]])
    table, rule = lam.table()(rows), lam._coefficients(rows)
    ggx = (np.sqrt(1 + rows[:, :1] ** 2 * np.tan(THETA) ** 2) - 1) / 2
    one_plus = 1 + ggx + _series(rule[:, 0])
    g1_error = np.abs(_series(table[:, 0] - rule[:, 0])) / one_plus     # |dG1 / G1| = |dLambda| / (1 + Lambda)
    assert g1_error.max() <= MAX_G1_ERROR, g1_error.max()


def test_table_derivatives_are_the_interpolants_own():
    """Central differences of the table's values equal its derivatives: a fit's Jacobian agrees with
    the values it differentiates (log axis: relative steps)."""
    tab = LAMBDA_GTR.table()
    rows = _box_rows(LAMBDA_GTR.box, 200, 2)
    rows[:, 0] = np.clip(rows[:, 0], 2e-4, 0.85)
    rows[:, 1] = np.clip(rows[:, 1], 1.1, 3.95)
    got = tab(rows)
    for k in (0, 1):
        step = 1e-6 * (rows[:, k] if tab.box.log[k] else np.ones(len(rows)))
        up, down = rows.copy(), rows.copy()
        up[:, k] += step
        down[:, k] -= step
        fd = (tab(up)[:, 0] - tab(down)[:, 0]) / (2 * step[:, None])
        scale = np.abs(got[:, 1 + k]).max(axis=1, keepdims=True) + 1e-30
        assert np.abs(fd - got[:, 1 + k]).max() / scale.max() < 1e-5


def test_rows_outside_the_box_get_the_rule_and_ggx_is_exact_on_its_line():
    lam = LAMBDA_GTR
    outside = np.array([[0.95, 1.5], [1.0, 3.0]])
    inside = np.array([[0.01, 1.5], [0.3, 2.0], [1e-3, 2.0]])
    rows = np.concatenate([outside, inside])
    values, derivs = lam.host_consts(alpha=rows[:, 0], gamma=rows[:, 1])
    rule = lam._coefficients(outside)
    for k, c in enumerate(lam.host):
        np.testing.assert_allclose(values[c][:2], rule[:, 0, k], rtol=1e-12, atol=1e-300)
        np.testing.assert_allclose(derivs[c]["alpha"][:2], rule[:, 1, k], rtol=1e-12, atol=1e-300)
    correction = np.stack([values[c][3:] for c in lam.host], axis=1)       # gamma = 2: GGX's Lambda, no correction
    assert np.abs(_series(correction)).max() < 1e-12
    assert lam.table().covers(np.array([[np.nan, 2.0]])).tolist() == [False]


def test_a_table_is_built_once_and_read_back(tmp_path, monkeypatch):
    """Kept in brdfcl's cache: a second series of the same box reads its table, with no call to the rule."""
    from brdfcl.model.terms.shadowing import smith_gtr
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path))
    box = Box(lo=(1e-2, 1.5), hi=(0.5, 2.5), log=(True, False), nodes=(6, 5))

    def series():
        return smith.SeriesLambda("smith_gtr", LAMBDA_GTR.inputs, LAMBDA_GTR.base, smith_gtr.gtr_integrand,
                                  smith_gtr.__name__, box=box)
    first, again, calls = series(), series(), []
    rule = first._coefficients
    first._coefficients = lambda rows: calls.append(len(rows)) or rule(rows)
    made = first.table()
    assert calls == [30] and isinstance(made, CoefficientTable)
    again._coefficients = lambda rows: pytest.fail("the rule ran again")
    np.testing.assert_array_equal(again.table().poly, made.poly)
