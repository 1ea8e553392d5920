"""The scattered-samples data layer: Samples geometry, sample weights, spectral -> RGB."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from brdfcl.data.errors import DataError
from brdfcl.data.samples import RGB_WAVELENGTHS_UM, Channel, Samples, make_samples, rgb_channels
from brdfcl.data.weights import DOMAIN_MEASURE, sample_weights

RNG_SEED = 1234


def _random_angles(n, seed=RNG_SEED):
    rng = np.random.default_rng(seed)
    ti = np.arccos(rng.uniform(0.05, 1.0, n))
    to = np.arccos(rng.uniform(0.05, 1.0, n))
    return ti, rng.uniform(-np.pi, np.pi, n), to, rng.uniform(-np.pi, np.pi, n)


def _samples(ti, pi_, to, po, channels=None, values=None):
    channels = rgb_channels() if channels is None else channels
    values = np.ones((np.size(ti), len(channels))) if values is None else values
    return make_samples(None, ti, pi_, to, po, values, channels)


# ---------------------------------------------------------------- Samples


def test_samples_are_frozen_and_read_only():
    s = _samples(*_random_angles(20))
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.name = "x"  # type: ignore[misc]
    for a in (s.theta_i, s.phi_i, s.theta_o, s.phi_o, s.values, s.weights, s.wi, s.wo):
        assert a.dtype == np.float64
        with pytest.raises(ValueError):
            a[0] = 1.0
    assert s.n_samples == 20 and s.n_channels == 3
    np.testing.assert_array_equal(s.wavelengths, [0.645, 0.526, 0.444])
    assert [c.name for c in s.channels] == list(RGB_WAVELENGTHS_UM)


def test_samples_check_shapes_and_channels():
    ti, pi_, to, po = _random_angles(5)
    with pytest.raises(ValueError, match="values shape"):
        Samples("x", None, ti, pi_, to, po, np.ones((5, 2)), rgb_channels(), np.ones(5))
    with pytest.raises(ValueError, match="one entry per sample"):
        Samples("x", None, ti, pi_, to, po[:4], np.ones((5, 3)), rgb_channels(), np.ones(5))
    with pytest.raises(ValueError, match="distinct"):
        Samples("x", None, ti, pi_, to, po, np.ones((5, 2)), (Channel("a", 0.5), Channel("a", 0.6)), np.ones(5))
    with pytest.raises(ValueError, match="positive"):
        Channel("a", -0.5)


def test_make_samples_reports_like_a_file():
    ti, pi_, to, po = _random_angles(4)
    with pytest.raises(DataError, match=r"^f\.csv:12: theta_o = 100 deg"):
        make_samples("f.csv", ti, pi_, np.r_[to[:3], np.radians(100)], po, np.ones((4, 3)), rgb_channels(),
                     lines=[3, 5, 9, 12])
    with pytest.raises(DataError, match=r"^f\.csv:5: value is NaN"):
        make_samples("f.csv", ti, pi_, to, po, np.r_[[[1, 1, 1]], [[1, np.nan, 1]], np.ones((2, 3))],
                     rgb_channels(), lines=[3, 5, 9, 12])
    with pytest.raises(DataError, match="no samples"):
        make_samples("f.csv", [], [], [], [], np.ones((0, 3)), rgb_channels())


def test_directions_and_mask():
    deg = np.radians
    s = _samples(deg([0, 30, 85, 60]), deg([0, 90, 0, 45]), deg([45, 30, 10, 90]), deg([180, -90, 0, 0]))
    np.testing.assert_allclose(s.wi[1], [0, 0.5, np.sqrt(3) / 2], atol=1e-15)
    np.testing.assert_allclose(s.wo[1], [0, -0.5, np.sqrt(3) / 2], atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(s.wo, axis=1), 1.0)
    np.testing.assert_allclose(s.cos_i, np.cos(deg([0, 30, 85, 60])))
    assert s.mask().tolist() == [True, True, False, False]            # 85 deg > 80; 90 deg at the horizon
    assert s.mask(None).tolist() == [True, True, True, False]
    assert s.mask(88).tolist() == [True, True, True, False]
    with pytest.raises(ValueError):
        s.mask(-5)


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def test_isotropic_angles_match_a_direct_construction():
    """Build (wi, wo) from chosen (theta_h, theta_d, phi_d, phi_h) with rotation matrices, read
    the spherical angles back, and recover the Rusinkiewicz angles (phi_d folded into [0, pi))."""
    rng = np.random.default_rng(7)
    rows, want = [], []
    while len(rows) < 300:
        th, td = rng.uniform(0, 0.5 * np.pi, 2)
        pd, ph = rng.uniform(0, 2 * np.pi, 2)
        d = np.array([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)])
        frame = _rot_z(ph) @ _rot_y(th)
        wi = frame @ d
        wo = frame @ (d * [-1, -1, 1])                     # d reflected about the local h = z
        if wi[2] < 0.01 or wo[2] < 0.01:
            continue
        rows.append([np.arccos(wi[2]), np.arctan2(wi[1], wi[0]), np.arccos(wo[2]), np.arctan2(wo[1], wo[0])])
        want.append([th, td, pd % np.pi])
    s = _samples(*np.array(rows).T)
    got = np.stack(s.isotropic(), axis=1)
    want = np.array(want)
    np.testing.assert_allclose(got[:, :2], want[:, :2], atol=1e-9)
    dphi = np.abs(got[:, 2] - want[:, 2])
    np.testing.assert_allclose(np.minimum(dphi, np.pi - dphi), 0, atol=1e-7)   # 0 and pi are one
    assert (got[:, 2] >= 0).all() and (got[:, 2] < np.pi).all()
    # the definitions themselves: cos theta_h = h . n, cos theta_d = wi . h
    h = (s.wi + s.wo) / np.linalg.norm(s.wi + s.wo, axis=1, keepdims=True)
    np.testing.assert_allclose(np.cos(got[:, 0]), h[:, 2], atol=1e-12)
    np.testing.assert_allclose(np.cos(got[:, 1]), np.sum(s.wi * h, axis=1), atol=1e-12)


def test_isotropic_reciprocity_and_specular():
    ti, pi_, to, po = _random_angles(50)
    a = np.stack(_samples(ti, pi_, to, po).isotropic())
    b = np.stack(_samples(to, po, ti, pi_).isotropic())       # wi <-> wo: same folded angles
    np.testing.assert_allclose(a[:2], b[:2], atol=1e-12)
    dphi = np.abs(a[2] - b[2])
    np.testing.assert_allclose(np.minimum(dphi, np.pi - dphi), 0, atol=1e-9)
    th, td, _ = _samples(np.radians([40.0]), [0.0], np.radians([40.0]), [np.pi]).isotropic()
    np.testing.assert_allclose([th[0], td[0]], [0.0, np.radians(40)], atol=1e-12)


# ---------------------------------------------------------------- weights


def _grid(n_theta=9, n_phi=12):
    """Cell centres of a regular (theta_i, theta_o, dphi) grid and each cell's exact dwi dwo."""
    te = np.radians(np.linspace(0, 90, n_theta + 1))
    pe = np.linspace(0, 2 * np.pi, n_phi + 1)
    i, o, p = (a.ravel() for a in np.meshgrid(np.arange(n_theta), np.arange(n_theta), np.arange(n_phi),
                                              indexing="ij"))
    band = np.cos(te[:-1]) - np.cos(te[1:])                        # int sin theta dtheta over each bin
    measure = 2 * np.pi * band[i] * band[o] * (pe[p + 1] - pe[p])
    tc, pc = 0.5 * (te[1:] + te[:-1]), 0.5 * (pe[1:] + pe[:-1])
    return tc[i], np.zeros(i.size), tc[o], pc[p], measure


def test_weights_on_a_regular_grid_approximate_the_cell_measures():
    ti, pi_, to, po, measure = _grid()
    assert measure.sum() == pytest.approx(DOMAIN_MEASURE)
    w = sample_weights(ti, pi_, to, po, cap=None)
    assert w.sum() == pytest.approx(DOMAIN_MEASURE, rel=1e-12)     # the cells partition the domain
    rel = np.abs(w / measure - 1)
    assert np.median(rel) < 0.03
    assert np.percentile(rel, 90) < 0.10
    assert rel.max() < 0.3                                          # worst near the normal
    # cells differ 30-fold in measure (sin theta): uniform weights would be far off
    assert measure.max() / measure.min() > 30
    # a rotation of the whole set about the normal changes nothing
    w2 = sample_weights(ti, pi_ + 0.7, to, po + 0.7, cap=None)
    np.testing.assert_allclose(w2, w, rtol=0.02)


def test_weights_within_a_cut_off_are_the_cell_measures_inside_it():
    ti, pi_, to, po, measure = _grid()
    w = sample_weights(ti, pi_, to, po, cap=None, cutoff_deg=60)
    inside = (ti < np.radians(60)) & (to < np.radians(60))
    assert (w[~inside] == 0).all() and (w[inside] > 0).all()
    assert w.sum() == pytest.approx((2 * np.pi * (1 - np.cos(np.radians(60)))) ** 2, rel=1e-12)
    rel = np.abs(w[inside] / measure[inside] - 1)
    assert np.median(rel) < 0.03 and np.percentile(rel, 90) < 0.10
    s = _samples(ti, pi_, to, po)
    np.testing.assert_array_equal(s.weights_within(60), sample_weights(ti, pi_, to, po, cutoff_deg=60))
    np.testing.assert_array_equal(s.weights_within(None), s.weights)
    assert (s.mask(60) == inside).all()
    with pytest.raises(ValueError, match="cut-off"):
        sample_weights(ti, pi_, to, po, cutoff_deg=0)


def test_duplicates_and_symmetric_images_share_their_weight():
    ti, pi_, to, po = _random_angles(200)
    w = sample_weights(ti, pi_, to, po, cap=None)
    # an exact copy of sample 0, the mirror image of sample 1, the reciprocal of sample 2
    ti2 = np.r_[ti, ti[0], ti[1], to[2]]
    pi2 = np.r_[pi_, pi_[0], -pi_[1], po[2]]
    to2 = np.r_[to, to[0], to[1], ti[2]]
    po2 = np.r_[po, po[0], -po[1], pi_[2]]
    w2 = sample_weights(ti2, pi2, to2, po2, cap=None)
    for k, extra in ((0, 200), (1, 201), (2, 202)):
        assert w2[k] == pytest.approx(w[k] / 2, rel=1e-12)
        assert w2[extra] == pytest.approx(w[k] / 2, rel=1e-12)
    np.testing.assert_allclose(w2[3:200], w[3:], rtol=1e-12)
    assert w2.sum() == pytest.approx(DOMAIN_MEASURE)


def test_azimuth_stops_mattering_at_the_normal():
    """With wi along the normal, samples differing only in phi are one configuration (a rotation
    about the normal maps one onto the other): they share one cell.  Near the normal the azimuth
    counts for little (r -> 0 in the metric)."""
    ti, pi_, to, po = (a[:60] for a in _random_angles(60))
    w = sample_weights(np.r_[ti, 0.0], np.r_[pi_, 0.0], np.r_[to, 0.5], np.r_[po, 0.0], cap=None)
    w2 = sample_weights(np.r_[ti, 0.0, 0.0], np.r_[pi_, 0.0, 0.0], np.r_[to, 0.5, 0.5], np.r_[po, 0.0, 2.0],
                        cap=None)
    assert w2[-1] == w2[-2] == pytest.approx(w[-1] / 2, rel=1e-12)
    from brdfcl.data.weights import embed
    near, far = embed([0.01, 0.01], [0.5, 0.5], [0.0, 2.0]), embed([0.5, 0.5], [0.5, 0.5], [0.0, 2.0])
    assert np.linalg.norm(near[0] - near[1]) < 0.02 < 0.5 < np.linalg.norm(far[0] - far[1])


def test_denser_samples_get_smaller_weights():
    ti, pi_, to, po = _random_angles(100)
    rng = np.random.default_rng(3)                 # 100 more samples crowded near one configuration
    k = 40
    jit = lambda a: a + rng.normal(0, 0.02, 100)  # noqa: E731
    ti2, to2 = np.clip(jit(np.full(100, ti[k])), 0, 1.5), np.clip(jit(np.full(100, to[k])), 0, 1.5)
    w = sample_weights(np.r_[ti, ti2], np.r_[pi_, np.full(100, pi_[k])], np.r_[to, to2],
                       np.r_[po, jit(np.full(100, po[k]))], cap=None)
    assert np.median(w[100:]) < 0.2 * np.median(w[:100])


def test_weight_cap_bounds_an_isolated_sample():
    # a dense cluster near normal incidence and one lone sample at grazing angles
    rng = np.random.default_rng(5)
    n = 300
    ti = np.r_[rng.uniform(0, 0.3, n), 1.4]
    to = np.r_[rng.uniform(0, 0.3, n), 1.4]
    pi_, po = np.zeros(n + 1), np.r_[rng.uniform(0, 2 * np.pi, n), np.pi]
    raw = sample_weights(ti, pi_, to, po, cap=None)
    w = sample_weights(ti, pi_, to, po)
    assert raw[-1] > 10 * np.median(raw)                 # without the cap it would dominate
    assert w[-1] == pytest.approx(10 * np.median(w))
    assert w.sum() < DOMAIN_MEASURE                       # the part cut off is counted as uncovered
    np.testing.assert_array_equal(w[:-1][raw[:-1] <= 10 * np.median(raw)], raw[:-1][raw[:-1] <= 10 * np.median(raw)])
    with pytest.raises(ValueError, match="cap"):
        sample_weights(ti, pi_, to, po, cap=0.5)


def test_weights_reject_bad_angles():
    with pytest.raises(ValueError, match="pi/2"):
        sample_weights([2.0], [0.0], [0.1], [0.0])
    with pytest.raises(ValueError, match="lengths"):
        sample_weights([0.1, 0.2], [0.0], [0.1], [0.0])
    with pytest.raises(ValueError, match="no samples"):
        sample_weights([], [], [], [])
    with pytest.raises(ValueError, match="finite"):
        sample_weights([0.1], [np.nan], [0.1], [0.0])


def test_make_samples_computes_weights_unless_given():
    ti, pi_, to, po = _random_angles(30)
    s = _samples(ti, pi_, to, po)
    np.testing.assert_array_equal(s.weights, sample_weights(ti, pi_, to, po))
    given = make_samples(None, ti, pi_, to, po, np.ones((30, 3)), rgb_channels(), weights=np.arange(30.0))
    np.testing.assert_array_equal(given.weights, np.arange(30.0))


# ---------------------------------------------------------------- spectral -> RGB


def _spectral(values, wavelengths_nm):
    values = np.atleast_2d(values)
    n = values.shape[0]
    ch = [Channel(f"{x:g}nm", x / 1000) for x in wavelengths_nm]
    return make_samples(None, np.full(n, 0.3), np.zeros(n), np.full(n, 0.4), np.full(n, np.pi), values, ch,
                        weights=np.ones(n))


def test_to_rgb_of_a_flat_spectrum_is_grey():
    pytest.importorskip("colour")
    from brdfcl.data import rgb
    wl = np.arange(400, 701, 10)
    s = _spectral(np.outer([0.0, 0.05, 0.3, 7.5], np.ones(wl.size)), wl)
    for ill in ("D65", "A", "E"):
        out = rgb.to_rgb(s, illuminant=ill)
        assert [c.name for c in out.channels] == ["R", "G", "B"]
        np.testing.assert_allclose(out.values, np.outer([0.0, 0.05, 0.3, 7.5], np.ones(3)), rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(out.weights, s.weights)
        np.testing.assert_array_equal(out.theta_o, s.theta_o)
    np.testing.assert_array_equal(rgb.to_rgb(s).wavelengths, list(RGB_WAVELENGTHS_UM.values()))


def test_to_rgb_colours_and_missing_values():
    pytest.importorskip("colour")
    from brdfcl.data.rgb import rgb_matrix, to_rgb
    wl = np.arange(400, 701, 10)
    red = np.where(wl >= 600, 0.5, 0.0)
    blue = np.where(wl <= 470, 0.5, 0.0)
    with_nan = np.full(wl.size, 0.2)
    with_nan[5] = np.nan
    out = to_rgb(Samples("x", None, [0.3] * 3, [0.0] * 3, [0.4] * 3, [np.pi] * 3, np.stack([red, blue, with_nan]),
                         tuple(Channel(f"{x}nm", x / 1000) for x in wl), np.ones(3))).values
    assert out[0, 0] > 5 * max(out[0, 1], out[0, 2], 0)
    assert out[1, 2] > 5 * max(out[1, 0], out[1, 1], 0)
    assert np.isnan(out[2]).all()
    np.testing.assert_allclose(rgb_matrix(wl / 1000).sum(axis=1), 1.0)
    with pytest.raises(ValueError, match="visible"):
        rgb_matrix(np.array([1.2, 1.5]))
    with pytest.raises(ValueError, match="illuminant"):
        rgb_matrix(wl / 1000, "no-such-light")


def test_effective_wavelengths_sample_linear_spectra_exactly():
    """The defining property: a channel samples a spectrum linear in wavelength at its effective
    wavelength.  (Channels spanning the whole 360-780 nm range, so the spectrum stays linear.)"""
    pytest.importorskip("colour")
    from brdfcl.data.rgb import effective_wavelengths, to_rgb
    lam = effective_wavelengths("D65")
    np.testing.assert_allclose(lam, (0.6424, 0.5430, 0.4408), atol=5e-4)         # stated in the docs
    np.testing.assert_allclose(lam, list(RGB_WAVELENGTHS_UM.values()), atol=0.02)  # near the MERL ones
    wl = np.arange(360, 781, 20)
    spectrum = 0.1 + 0.4 * (wl / 1000)
    out = to_rgb(_spectral(spectrum, wl), effective=True)
    np.testing.assert_allclose(out.wavelengths, lam)
    np.testing.assert_allclose(out.values[0], 0.1 + 0.4 * np.array(lam), rtol=1e-9)


def test_to_rgb_leaves_rgb_samples_alone():
    pytest.importorskip("colour")
    from brdfcl.data.rgb import to_rgb
    s = _samples(*_random_angles(5))
    assert to_rgb(s) is s
