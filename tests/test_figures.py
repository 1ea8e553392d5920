"""The analysis figures (brdfcl.report.figures): they show what the tests compute.  Fast: no fit, synthetic
tables and stand-in fit results."""
from types import SimpleNamespace

import numpy as np
import pytest

from brdfcl.analysis.gradient import gradient_test, phi90_slice
from brdfcl.analysis.wavelength import wavelength_check
from brdfcl.model.compose import Model
from brdfcl.model.lobes.diffraction import LAMBDAS
from brdfcl.model.synth import DEMO, demo_values, tabulate
from brdfcl.report import figures as report
from brdfcl.report import style as FS
from brdfcl.report.writers.analysis_index import write_index

SPEC = "diffuse+diffraction:hp:none+ggx:smith:schlick"


@pytest.fixture(scope="module")
def smooth_metal():
    """The demo's diffraction material, with its own parameters standing in for the fits."""
    spec, params = DEMO["synth-smooth-metal"]
    m = Model(spec)
    brdf = tabulate(m, demo_values(m, params))
    measured = phi90_slice(brdf)[0]
    rng = np.random.default_rng(1)
    full = measured * np.exp(rng.normal(0.0, 0.1, measured.shape))      # a fit with a residual
    slices = {"measured": measured, "full": full, "diffuse_diffraction": 0.6 * full, "ct": 0.4 * full}
    return SimpleNamespace(name="synth-smooth-metal", gradient=gradient_test(brdf),
                           wavelength=wavelength_check(brdf, [p / np.pi for p in params["diffuse.rho"]]),
                           specs={"full": SPEC}, slices=slices, law_ratio=0.8765,
                           fits={"full": SimpleNamespace(errors={"rmse_log": 0.1})})


def test_vote_map_counts_are_the_gradient_tests(smooth_metal):
    g = smooth_metal.gradient
    v = report.vote_map(g)
    assert v.shape == g.decidable.shape
    for c in range(3):
        n_diff = (v[c] == FS.VOTE_DIFFRACTION).sum()
        n_ct = (v[c] == FS.VOTE_CT).sum()
        assert n_diff == g.consistent[c].sum()
        assert n_diff + n_ct == g.n_cells[c]
        assert n_diff / (n_diff + n_ct) == pytest.approx(g.score[c])
        assert ((v[c] == FS.VOTE_OUTSIDE) == ~g.region).all()
    assert g.mean_score > 0.9 and (v == FS.VOTE_DIFFRACTION).sum() > (v == FS.VOTE_CT).sum()


def test_vote_map_of_a_material_without_diffraction():
    m = Model("diffuse+ggx:smith:none")
    g = gradient_test(tabulate(m, demo_values(m, {"ct.rho": (0.8,) * 3, "ct.alpha": 0.2})))
    v = report.vote_map(g)
    assert (v == FS.VOTE_CT).sum() > 100
    assert [(v[c] == FS.VOTE_CT).sum() + (v[c] == FS.VOTE_DIFFRACTION).sum() for c in range(3)] == list(g.n_cells)


def test_wavelength_figure_plots_the_curves_of_the_ratio(smooth_metal):
    w = smooth_metal.wavelength
    curves = report.wavelength_curves(w, LAMBDAS)
    mid = np.sqrt(w.edges[1:] * w.edges[:-1])
    for key, ref, x_ref, spread in (("f_c", w.curves, mid, w.spread),
                                    ("f0", w.curves_f0, mid * LAMBDAS[1], w.spread_f0)):
        x, y, common = curves[key]
        np.testing.assert_array_equal(y, ref)
        np.testing.assert_allclose(x, x_ref)
        # the spread is computed on exactly these curves, over the bins where all channels have a value
        ly = np.log(y[:, common])
        assert np.sqrt(np.mean((ly - ly.mean(axis=0)) ** 2)) == pytest.approx(spread, rel=1e-9)
    assert w.ratio < 1


def test_wavelength_figure_draws_them(smooth_metal, tmp_path):
    fig = report.figure_wavelength(smooth_metal, tmp_path / "w.png")
    assert (tmp_path / "w.png").stat().st_size > 10000
    curves = report.wavelength_curves(smooth_metal.wavelength, LAMBDAS)
    for ax, key in zip(fig.axes[:2], ("f_c", "f0")):
        x, y, _ = curves[key]
        drawn = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
        assert len(drawn) == 3
        for c, ln in enumerate(drawn):
            ok = np.isfinite(y[c]) & (y[c] > 0)
            np.testing.assert_array_equal(ln.get_ydata(), y[c][ok])
            np.testing.assert_array_equal(ln.get_xdata(), x[ok])
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert [lab[0] for lab in labels[:3]] == list("RGB")
    assert f"{smooth_metal.wavelength.ratio:.2f}" in fig._suptitle.get_text()
    assert f"{smooth_metal.law_ratio:.3f}" in fig._suptitle.get_text()


def test_gradient_figure_shows_vote_and_angle_per_channel(smooth_metal, tmp_path):
    fig = report.figure_gradient(smooth_metal, tmp_path / "g.png")
    assert (tmp_path / "g.png").stat().st_size > 10000
    titles = [ax.get_title() for ax in fig.axes]
    g = smooth_metal.gradient
    for c, ch in enumerate("RGB"):
        assert any(t.startswith(f"{ch}: score {g.score[c]:.2f}\n= {g.consistent[c].sum()} diffraction")
                   for t in titles)
        assert f"{ch}: angle of grad p to grad f" in titles
    legend = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
    assert {"diffraction", "Cook-Torrance"} <= set(legend) and any(t.startswith("undecided") for t in legend)
    assert all(f"{ch} {s:.2f}" in fig._suptitle.get_text() for ch, s in zip("RGB", g.score))


def test_components_figure_has_rgb_and_residual(smooth_metal, tmp_path):
    fig = report.figure_components(smooth_metal, tmp_path / "c.png")
    assert (tmp_path / "c.png").stat().st_size > 10000
    titles = {ax.get_title() for ax in fig.axes}
    for ch in "RGB":
        for part in ("measured", "diffuse + diffraction", "Cook-Torrance", "full model"):
            assert f"{ch}: {part}" in titles
        assert any(t.startswith(f"{ch}: residual") for t in titles)
    res = report.residual(smooth_metal)
    ok = np.isfinite(res)
    s = smooth_metal.slices
    np.testing.assert_allclose(res[ok], np.log(s["measured"][ok] / s["full"][ok]))
    # the residual's colour map is diverging and centred on 0
    resid_ax = next(ax for ax in fig.axes if ax.get_title().startswith("G: residual"))
    mesh = resid_ax.collections[0]
    assert mesh.cmap.name == FS.RESIDUAL_CMAP and mesh.norm.vmin == pytest.approx(-mesh.norm.vmax)
    labels = [ax.get_xlabel() + ax.get_ylabel() for ax in fig.axes]
    assert any("1/sr" in lab for lab in labels) and any("ln(measured / fitted)" in lab for lab in labels)


def test_figures_are_sized_for_a_1400px_page(smooth_metal, tmp_path):
    from PIL import Image
    for k in ("gradient", "wavelength", "components"):
        getattr(report, f"figure_{k}")(smooth_metal, tmp_path / f"{k}.png")
        w, h = Image.open(tmp_path / f"{k}.png").size
        assert w == 1400 and 400 < h < 1200, (k, w, h)


def test_index_fits_the_page(smooth_metal, tmp_path):
    a = SimpleNamespace(name="synth-smooth-metal", row=lambda: {
        "material": "synth-smooth-metal", "verdict": "diffraction", "selected_lobes": SPEC,
        "final_model": SPEC, **{c: "0.12345" for c in (
            "grad_score_g", "grad_cells", "grad_band_deg_g", "law_ratio", "collapse_ratio", "rmse_log_full",
            "rmse_log_no_diffraction", "rmse_log_no_ct", "peak_share_diffraction", "rmse_log_full_free",
            "peak_share_free")}})
    write_index(tmp_path, [a])
    page = (tmp_path / "index.html").read_text()
    assert "<th title='rmse_log_no_diffraction'>" in page          # short headers, the CSV name in a tooltip
    assert "diffuse+<wbr>diffraction" in page                        # long lobe specs wrap
    assert "width:32%" not in page and "max-width:1400px" in page    # figures at their own size
