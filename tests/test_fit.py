"""Fitting: parameter recovery, outputs, resume, determinism, and the global search's worth."""
import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from brdfcl.app.run import fit_all
from brdfcl.data.merl import read_merl
from brdfcl.optim.fit import FitOptions, Fitter
from brdfcl.optim.status import Status


def _fit(paths, **kw):
    return Fitter(FitOptions(**kw)).fit([read_merl(p) for p in paths])


def test_recovers_every_demo_parameter(demo_db):
    truth = json.loads((demo_db / "truth.json").read_text())["materials"]
    for name, t in truth.items():
        (r,) = _fit([demo_db / f"{name}.binary"], model=t["model"])
        assert r.success, r.status
        # exact fits stop at the float32 floor: converged, even where the final stage used its cap
        assert Status(r.status).converged, (name, r.message)
        for k, v in t["params"].items():
            assert r.params[k] == pytest.approx(v, rel=0.01), (name, k)


def test_exact_fits_in_the_default_batch_stop_converged(demo_db):
    """The demo's five materials in one batch with the default model: the exact ones (mirror, smooth
    metal) stop at the float32 noise floor as converged instead of stepping on rounding noise until
    the iteration limit (they did once the starts were ranked on the preview cells)."""
    res = {r.name: r for r in _fit(sorted(demo_db.glob("*.binary")))}
    for name in ("synth-mirror", "synth-smooth-metal"):
        assert res[name].errors["rmse_log"] < 1e-5 and Status(res[name].status).converged, res[name].message


@pytest.mark.slow
def test_fit_all_outputs_resume_and_export(demo_db, tmp_path):
    out = tmp_path / "out"
    args = [sys.executable, "-m", "brdfcl.app.cli", "fit-all", str(demo_db), "--out", str(out),
            "--model", "diffuse+ggx", "--export-merl"]
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "%|" not in r.stderr                      # no progress bar when not a terminal
    rows = list(csv.DictReader(open(out / "summary.csv")))
    assert [row["material"] for row in rows] == sorted(p.stem for p in demo_db.glob("*.binary"))
    assert list(rows[0])[:9] == ["material", "model", "metric", "seconds", "evaluations", "rmse_log",
                                 "rmse_l2", "rmse_cbrt", "rel_rmse"]
    assert "ct.alpha" in rows[0] and "diffuse.rho_r" in rows[0]
    doc = json.loads((out / "synth-mirror.json").read_text())
    assert doc["params"]["ct.alpha"]["value"] == pytest.approx(1e-3, rel=0.05)
    assert {"unit", "lo", "hi"} <= set(doc["params"]["ct.alpha"]) and doc["brdfcl_version"]
    assert doc["history"] and doc["errors"]["rmse_log"] < 1e-3
    exported = read_merl(out / "synth-mirror.binary")
    original = read_merl(demo_db / "synth-mirror.binary")
    ok = exported.valid & original.valid
    rel = np.abs(exported.brdf()[:, ok] / original.brdf()[:, ok] - 1)
    assert np.median(rel) < 0.01
    mtime = (out / "synth-mirror.json").stat().st_mtime_ns
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 0 and "5 already done" in r.stdout
    assert (out / "synth-mirror.json").stat().st_mtime_ns == mtime


def test_deterministic_for_a_seed(demo_db):
    paths = [demo_db / "synth-rough-metal.binary", demo_db / "synth-fabric.binary"]
    a = _fit(paths, seed=3)
    b = _fit(paths[::-1], seed=3)          # batch order does not matter either
    for ra in a:
        rb = next(r for r in b if r.name == ra.name)
        assert ra.params == rb.params


def test_proxy_fits_and_global_search_earns_its_time(proxy_pair):
    from tests.conftest import proxy_files
    paths = proxy_pair + proxy_files(["brass", "blue-fabric"])
    glob = {r.name: r for r in _fit(paths)}
    single = {r.name: r for r in _fit(paths, global_method="none")}
    for name, r in glob.items():
        assert r.success and np.isfinite(r.errors["rmse_log"]), (name, r.status)
        assert r.errors["rmse_log"] <= single[name].errors["rmse_log"] * (1 + 1e-3), name


def test_python_api_fit_all(demo_db, tmp_path):
    rep = fit_all([demo_db / "synth-fabric.binary"], tmp_path, model="diffuse+beckmann:vcavity:none")
    assert rep.ok and rep.results[0].params["ct.alpha"] == pytest.approx(0.6, rel=0.01)
    assert (tmp_path / "synth-fabric.json").exists()


def test_warm_start_skips_the_global_stage_and_recovers(demo_db):
    """``Fitter.fit(start=...)``: the local stage from given values, no global search."""
    t = json.loads((demo_db / "truth.json").read_text())["materials"]["synth-smooth-plastic"]
    f = Fitter(FitOptions(model=t["model"]))
    tables = [read_merl(demo_db / "synth-smooth-plastic.binary")]
    truth = np.array([t["params"].get(n, np.nan) for n in f.model.names])
    assert np.isfinite(truth).all()
    start = truth * np.where(np.arange(truth.size) % 2, 1.25, 0.8)       # every parameter 20-25% off
    (r,) = f.fit(tables, start=start[None])
    (cold,) = Fitter(FitOptions(model=t["model"])).fit(tables)
    assert r.success and r.nfev < cold.nfev / 5                       # the global stage's evaluations skipped
    for k, v in t["params"].items():
        assert r.params[k] == pytest.approx(v, rel=0.01), k
    with pytest.raises(ValueError, match="start values of shape"):
        f.fit(tables, start=truth[None, :-1])


def test_each_material_has_its_share_of_the_batch_time(demo_db):
    """A launch serves every material in it: a material's seconds are its share of the batch's
    wall time, so the shares add up to it (not each the whole batch's)."""
    tables = [read_merl(demo_db / f"{n}.binary") for n in ("synth-fabric", "synth-mirror", "synth-smooth-metal")]
    res = Fitter(FitOptions(model="diffuse+ggx")).fit(tables)
    total = res[0].stages["total"]
    assert all(r.stages["total"] == total for r in res)
    assert sum(r.seconds for r in res) == pytest.approx(total, rel=0.05)
    assert all(0 < r.seconds < total for r in res)


def test_finite_weights_count_each_finite_value_once():
    """The loss's normalisation: the weights of the finite values summed over channels, for a place
    that materials share and for one of their own, with NaN, inf and -inf among the values."""
    from brdfcl.data.geometry import TABLE
    from brdfcl.device.cellsets import select_cells
    from brdfcl.device.engine import Place
    from brdfcl.optim.fit import finite_weights

    index = select_cells(80.0)[::97]
    shared, own = Place(TABLE, index), Place(TABLE, index[::2], 4.0)
    rng = np.random.default_rng(3)
    values = [rng.random((3, index.size)).astype(np.float32) for _ in range(3)] + \
        [rng.random((3, index[::2].size)).astype(np.float32)]
    values[1][0, 5], values[1][2, 5], values[1][1, 9] = np.nan, np.inf, -np.inf
    values[3][2, 0] = np.nan
    places = [shared, shared, shared, own]
    got = finite_weights(values, places, 80.0)
    want = [np.sum(np.isfinite(v) * p.weights(80.0)) for v, p in zip(values, places)]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert got[1] < got[0]
