"""The diffraction analysis: the gradient test, the wavelength check, verdicts and outputs."""
import csv
import subprocess
import sys

import numpy as np
import pytest

from brdfcl.analysis.gradient import gradient_test, line_angle
from brdfcl.analysis.wavelength import wavelength_check
from brdfcl.app.analyze import analyze
from brdfcl.model.compose import Model
from brdfcl.model.synth import demo_values, tabulate


def _table(spec, params):
    m = Model(spec)
    return tabulate(m, demo_values(m, params))


def test_line_angle():
    assert line_angle(1.0, 0.0, -2.0, 0.0) == pytest.approx(0.0)
    assert line_angle(1.0, 0.0, 0.0, 3.0) == pytest.approx(90.0)
    assert line_angle(1.0, 1.0, 1.0, 0.0) == pytest.approx(45.0)


def test_pure_diffraction_follows_level_lines_of_f():
    t = _table("diffuse+diffraction:hp", {"diffuse.rho": (0.01, 0.01, 0.01),
                                          "diffraction.rho": (0.05, 0.05, 0.05), "diffraction.a": 0.5})
    g = gradient_test(t)
    dec = g.significant & g.region[None]
    assert dec.sum() > 1000
    assert np.nanmedian(g.angle_f[dec]) < 2.0
    assert g.mean_score > 0.95
    w = wavelength_check(t, [0.01 / np.pi] * 3)
    assert w.ratio < 0.5 and w.consistent


@pytest.mark.slow
def test_specular_lobe_is_not_diffraction():
    """A Cook-Torrance lobe's level lines at phi_d = 90 are tilted by 1/(cos ti cos to), half as
    much as f's in its tails: against a bare theta_h axis it scored ~0.7; against the CT prediction
    the test gives it to CT, with or without a Fresnel factor.  It also has no wavelength dependence."""
    for spec, extra in (("ggx:smith:none", {}), ("diffuse+ggx:smith:schlick", {"ct.F0": (0.9,) * 3}),
                        ("diffuse+ggx:smith:dielectric", {"ct.eta": 1.5, "diffuse.rho": (0.002,) * 3}),
                        ("diffuse+beckmann:smith:none", {})):
        for alpha in (0.05, 0.2):
            t = _table(spec, {"ct.rho": (0.8, 0.8, 0.8), "ct.alpha": alpha, **extra})
            g = gradient_test(t)
            assert g.n_cells.sum() > 100 and g.mean_score < 0.25, (spec, alpha, g.score)
    t = _table("ggx:smith:none", {"ct.rho": (0.8, 0.8, 0.8), "ct.alpha": 0.05})
    w = wavelength_check(t)
    assert w.consistent is False and w.ratio > 10          # no wavelength dependence at all


def test_diffraction_halo_around_a_specular_peak_passes():
    """The talk's picture: a CT peak and a diffraction halo (the Fresnel slope is read off the ridge)."""
    from brdfcl.model.synth import DEMO
    g = gradient_test(_table(*DEMO["synth-smooth-metal"]))
    assert g.n_cells.sum() > 1000 and g.mean_score > 0.9


def test_missing_cells_do_not_break_the_test():
    t = _table("diffuse+diffraction:hp", {"diffraction.rho": (0.05, 0.04, 0.03), "diffraction.a": 0.5})
    rng = np.random.default_rng(0)
    t[:, rng.random(t.shape[1]) < 0.2] = np.nan
    g = gradient_test(t)
    assert np.isfinite(g.score).all() and g.mean_score > 0.9


@pytest.mark.slow
def test_demo_verdicts_and_outputs(demo_db, tmp_path):
    res = {a.name: a for a in analyze(demo_db, tmp_path)}
    verdicts = {n: a.verdict for n, a in res.items()}
    assert verdicts == {"synth-smooth-metal": "diffraction", "synth-rough-metal": "none",
                        "synth-smooth-plastic": "none", "synth-fabric": "none", "synth-mirror": "none"}
    assert "diffraction" not in res["synth-smooth-plastic"].final_model
    assert "diffraction" in res["synth-smooth-metal"].final_model
    assert res["synth-smooth-metal"].peak_share_diffraction < 0.5    # the peak is CT's
    rows = list(csv.DictReader(open(tmp_path / "analysis.csv")))
    assert len(rows) == 5 and {"verdict", "selected_lobes", "grad_score_g", "law_ratio", "collapse_ratio",
                               "rmse_log_no_diffraction"} <= set(rows[0])
    import OpenEXR
    with OpenEXR.File(str(tmp_path / "synth-smooth-metal.exr")) as f:
        ch = f.channels()
        assert {"angle_f", "measured", "ct", "diffuse_diffraction", "consistent"} <= set(ch)
        assert ch["angle_f"].pixels.shape == (90, 90, 3) and ch["angle_f"].pixels.dtype == np.float32
    for k in ("gradient", "wavelength", "components"):
        assert (tmp_path / "figures" / f"synth-smooth-metal_{k}.png").stat().st_size > 10000
    page = (tmp_path / "index.html").read_text()
    assert page.count("<tr class=") == 5 and "synth-smooth-metal_components.png" in page


@pytest.mark.slow
def test_fit_all_select_lobes(demo_db, tmp_path):
    paths = [str(demo_db / "synth-smooth-plastic.binary"), str(demo_db / "synth-smooth-metal.binary")]
    d = tmp_path / "db"
    d.mkdir()
    for p in paths:
        (d / p.split("/")[-1]).symlink_to(p)
    r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "fit-all", str(d), "--out", str(tmp_path / "o"),
                        "--select-lobes", "--quiet"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rows = {row["material"]: row for row in csv.DictReader(open(tmp_path / "o" / "summary.csv"))}
    assert "diffraction" not in rows["synth-smooth-plastic"]["model"]
    assert "diffraction" in rows["synth-smooth-metal"]["model"]
    r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "fit-all", str(d), "--out", str(tmp_path / "o"),
                        "--select-lobes", "--quiet"], capture_output=True, text=True)
    assert "2 already done" in r.stdout
