"""brdfcl analyze on scattered spectral samples: the verdict on synthetic materials of known
diffraction, the report's contents, and the real Cornell measurement."""
import csv

import numpy as np
import pytest

from brdfcl.analysis.samples import GRADIENT_NOT_RUN, SAMPLE_RULE
from brdfcl.app.analyze import analyze
from brdfcl.data.csvsamples import write_csv
from brdfcl.data.samples import Channel, make_samples
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.report.sample_figures import in_plane, incidence_panels

# -n with --dist loadgroup (the slow tier in .ci/run): one process runs this module's tests, not
# one after another, so its costly fixture is session-scoped: made once there
pytestmark = pytest.mark.xdist_group("test_analyze_samples")

LAMBDAS = tuple(np.round(np.linspace(0.40, 0.70, 11), 3))
CHANNELS = [Channel(f"{x * 1000:g}nm", x) for x in LAMBDAS]


def _material(name, spec, params, made_at=LAMBDAS, n=1500, seed=0):
    """Samples of ``spec`` at random directions, made with the bands ``made_at`` (labelled LAMBDAS),
    1% multiplicative noise."""
    rng = np.random.default_rng(seed)
    ti = rng.choice(np.radians(np.arange(10, 80, 10)), n)           # an instrument's incidence angles
    to = np.arccos(rng.uniform(0.2, 0.98, n))
    pi, po = np.zeros(n), rng.uniform(-np.pi, np.pi, n)
    po[: n // 8] = rng.choice([0.0, np.pi], n // 8)                 # some in the plane of incidence
    model = Model(spec, lambdas=made_at)
    v = model.as_dict(model.defaults())
    for i, c in enumerate(model.channels):
        for k, val in params.items():
            if f"{k}_{c}" in v:
                v[f"{k}_{c}"] = val(LAMBDAS[i]) if callable(val) else val
    v.update({k: val for k, val in params.items() if k in v})
    flat = make_samples(None, ti, pi, to, po, np.ones((n, len(CHANNELS))), CHANNELS, name=name)
    p = model.reference(Cells.from_directions(flat.wi, flat.wo), model.only_lobes(v, None), jacobian=False)
    p = p.T * np.exp(0.01 * rng.normal(size=p.T.shape))
    return make_samples(None, ti, pi, to, po, p, CHANNELS, name=name)


DIFFRACTING = {"diffuse.rho": 0.02, "diffraction.rho": 0.04, "diffraction.a": 2.0,
               "ct.rho": 0.3, "ct.alpha": 0.05}
PLASTIC = {"diffuse.rho": lambda lam: 0.05 + 0.3 * (lam - 0.4), "ct.rho": 0.4, "ct.alpha": 0.08}


@pytest.fixture(scope="session")
def analysed(tmp_path_factory):
    src = tmp_path_factory.mktemp("spectral")
    write_csv(_material("diffracting", "diffuse+diffraction+ggx", DIFFRACTING), src / "diffracting.csv")
    write_csv(_material("plastic", "diffuse+ggx", PLASTIC, seed=1), src / "plastic.csv")
    # a halo made at one wavelength in every band: scattering that ignores the wavelength
    grey = tuple(0.55 + 1e-4 * i for i in range(len(LAMBDAS)))
    write_csv(_material("grey-halo", "diffuse+diffraction+ggx", DIFFRACTING, made_at=grey, seed=2),
              src / "grey-halo.csv")
    out = tmp_path_factory.mktemp("out") / "a"
    results = analyze(src, out, pages=True)
    return {a.name: a for a in results}, out


@pytest.mark.slow
def test_the_verdicts_of_known_materials(analysed):
    res, _ = analysed
    assert res["diffracting"].verdict == "diffraction"
    assert res["diffracting"].law_ratio < 0.5 and res["diffracting"].spectral.ratio < 0.5
    assert abs(res["diffracting"].spectral.exponent - 4.0) < 0.3
    assert res["plastic"].verdict == "none" and res["plastic"].final_model.count("diffraction") == 0
    grey = res["grey-halo"]
    assert grey.verdict == "none" and grey.law_ratio > 2
    assert "wavelength" in grey.margins()["verdict_by"]
    assert all(a.rule == SAMPLE_RULE for a in res.values())
    assert all(a.row()["verdict_by"] for a in res.values())


@pytest.mark.slow
def test_the_diffracting_fit_recovers_its_parameters(analysed):
    res, _ = analysed
    p = res["diffracting"].fits["full"].params
    assert p["ct.alpha"] == pytest.approx(0.05, rel=0.02)
    assert p["diffraction.a"] == pytest.approx(2.0, rel=0.05)
    for c in Model("diffuse+diffraction+ggx", lambdas=LAMBDAS).channels:
        assert p[f"diffraction.rho_{c}"] == pytest.approx(0.04, rel=0.05)


@pytest.mark.slow
def test_the_report_says_what_was_run(analysed):
    _, out = analysed
    rows = {r["material"]: r for r in csv.DictReader((out / "analysis.csv").open())}
    assert set(rows) == {"diffracting", "plastic", "grey-halo"}
    for r in rows.values():
        assert r["gradient_test"] == GRADIENT_NOT_RUN and r["margin_gradient"] == ""
        assert r["data"] == "1500 scattered samples, 11 bands"
        assert float(r["law_ratio"]) > 0 and int(r["law_cells"]) > 100 and r["lambda_exponent"] != ""
    res, _ = analysed
    for name in rows:
        mask, _ = in_plane(res[name].samples)
        assert len(incidence_panels(res[name].samples, mask)) == 4      # the in-plane figure has its panels
        assert (out / "figures" / f"{name}_spectral.png").stat().st_size > 10000
        assert (out / "figures" / f"{name}_in_plane.png").stat().st_size > 10000
        assert not (out / f"{name}.exr").exists()
    index = (out / "index.html").read_text()
    assert "gradient test not run: scattered samples have no (theta_h, theta_d) grid" in index
    assert "figures/diffracting_spectral.png" in index
    page = (out / "report" / "diffracting.html").read_text()
    assert "Measured samples and the fit in the plane of incidence" in page
    assert "diffracting_spectral.png" in page


@pytest.mark.slow
def test_krylon_is_analysed(krylon, tmp_path):
    (a,) = analyze([krylon.path], None)
    assert a.verdict == "none" and "lobe" in a.margins()["verdict_by"].split("+") and a.spectral is not None
    assert a.spectral.n_wide > 1000 and len(a.spectral.wavelengths) == 31
    assert a.fits["full"].errors["rel_rmse"] < 0.3
    assert a.row()["gradient_test"] == GRADIENT_NOT_RUN


def test_the_sample_rule_reads_the_law_as_the_table_rule():
    """A verdict means one thing: the samples' rule is the tables' rule, without requiring the
    gradient test (not run on samples), so that the evidence must come from the law."""
    from dataclasses import replace

    from brdfcl.analysis.analyze import RULE
    assert SAMPLE_RULE.wavelength_test == "law" and not SAMPLE_RULE.gradient_required
    assert replace(SAMPLE_RULE, gradient_required=RULE.gradient_required) == RULE
    assert SAMPLE_RULE.verdict(SAMPLE_RULE.margins(float("nan"), 0, 0.5, 0.3)) == "diffraction"
    assert SAMPLE_RULE.verdict(SAMPLE_RULE.margins(float("nan"), 0, float("nan"), 0.3)) == "none"
