"""The per-material choice of a reflection lobe's form (brdfcl.optim.forms): candidates written
from a model, and the true form of synthetic materials recovered by the penalised error."""
import json
import subprocess
import sys

import numpy as np
import pytest

from brdfcl.data.samples import Channel, make_samples
from brdfcl.model.compose import Model, ModelError
from brdfcl.model.lobes.cells import Cells
from brdfcl.optim.fit import FitOptions, Fitter
from brdfcl.optim.forms import choose_form, form_variants, parse_forms

LAMBDAS = (0.45, 0.55, 0.65)
TRUTH = {   # true form -> its reflection lobe's shape parameters
    "ggx:schlick": {"ct.alpha": 0.12},
    "ggx:dielectric": {"ct.alpha": 0.12, "ct.eta": 1.5},
    "gtr:schlick": {"ct.alpha": 0.05, "ct.gamma": 1.3},
    "gtr:dielectric": {"ct.alpha": 0.05, "ct.gamma": 1.3, "ct.eta": 1.5},
    "beckmann:schlick": {"ct.alpha": 0.2},
    "beckmann:dielectric": {"ct.alpha": 0.2, "ct.eta": 1.6},
}


def test_variants_keep_the_other_lobes_and_the_shadowing_word():
    v = form_variants("diffuse+diffraction+ggx:smith-hc:schlick", ("ggx", "gtr"), ("schlick", "dielectric"))
    assert v["gtr:dielectric"] == "diffuse+diffraction:hp:none+gtr:smith-hc:dielectric"
    assert set(v) == {"ggx:schlick", "ggx:dielectric", "gtr:schlick", "gtr:dielectric"}
    assert set(form_variants("diffuse+ggx", (), ("dielectric",))) == {"ggx:dielectric"}   # its own NDF
    with pytest.raises(ModelError, match="form sgd:schlick of 'diffuse\\+ggx'"):   # sgd has no Smith term
        form_variants("diffuse+ggx", ("sgd",), ())
    assert parse_forms("GGX, gtr :dielectric") == (("ggx", "gtr"), ("dielectric",))
    with pytest.raises(ModelError, match="unknown ndf foo"):
        parse_forms("ggx,foo")


def _material(form, seed):
    ndf, fresnel = form.split(":")
    model = Model(f"diffuse+{ndf}:smith:{fresnel}", lambdas=LAMBDAS)
    v = model.as_dict(model.defaults())
    for c, rd, f0 in zip(model.channels, (0.05, 0.08, 0.12), (0.9, 0.7, 0.5)):
        v[f"diffuse.rho_{c}"], v[f"ct.rho_{c}"] = rd, 0.8
        if f"ct.F0_{c}" in v:
            v[f"ct.F0_{c}"] = f0
    v.update(TRUTH[form])
    rng = np.random.default_rng(seed)
    n = 1500
    ti, to = np.arccos(rng.uniform(0.2, 1.0, n)), np.arccos(rng.uniform(0.2, 1.0, n))
    pi, po = np.zeros(n), rng.uniform(-np.pi, np.pi, n)
    po[: n // 3] = np.pi + rng.normal(0, 0.05, n // 3)          # a third near the plane: the peak
    to[: n // 3] = ti[: n // 3] + rng.normal(0, 0.08, n // 3)
    to = np.clip(to, 0.0, 1.37)
    ch = [Channel(f"{x * 1000:g}nm", x) for x in LAMBDAS]
    flat = make_samples(None, ti, pi, to, po, np.ones((n, 3)), ch)
    p = model.reference(Cells.from_directions(flat.wi, flat.wo), model.only_lobes(v, None), jacobian=False)
    p = p.T * np.exp(0.01 * rng.normal(size=p.T.shape))
    return make_samples(None, ti, pi, to, po, p, ch, name=form)


def test_the_true_form_of_each_synthetic_material_is_chosen():
    samples = [_material(form, seed) for seed, form in enumerate(TRUTH)]
    specs = form_variants("diffuse+ggx:smith:schlick", ("ggx", "gtr", "beckmann"), ("schlick", "dielectric"))
    assert len(specs) == 6
    errors: dict = {s.name: {} for s in samples}
    for key, spec in specs.items():
        for r in Fitter(FitOptions(model=spec), lambdas=LAMBDAS).fit_samples(samples):
            errors[r.name][key] = r.errors["rmse_log"]
    for s in samples:
        chosen, pen = choose_form(errors[s.name], specs)
        assert chosen == s.name, (s.name, {k: round(v, 5) for k, v in pen.items()})


def test_fit_all_records_the_chosen_form(demo_db, tmp_path):
    src, out = tmp_path / "in", tmp_path / "o"
    src.mkdir()
    for name in ("synth-rough-metal", "synth-smooth-plastic"):
        (src / f"{name}.binary").symlink_to(demo_db / f"{name}.binary")
    r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "fit-all", str(src), "--out", str(out),
                        "--select-lobes", "--forms", "ggx,beckmann:schlick,dielectric", "--quiet", "--no-report"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    rough = json.loads((out / "synth-rough-metal.json").read_text())
    plastic = json.loads((out / "synth-smooth-plastic.json").read_text())
    assert rough["form"] == "beckmann:schlick" and rough["model"] == "diffuse+beckmann:smith:schlick"
    assert plastic["form"] == "ggx:dielectric" and plastic["verdict"] == "none"
    assert set(rough["form_errors"]) == {"ggx:schlick", "ggx:dielectric", "beckmann:schlick", "beckmann:dielectric"}
    assert rough["options"]["forms"] == sorted(rough["form_errors"])
    bad = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "fit-all", str(demo_db), "--out", str(tmp_path / "b"),
                          "--forms", "ggx,beckmann"], capture_output=True, text=True)
    assert bad.returncode != 0 and "Traceback" not in bad.stderr
    assert "--forms chooses among forms in the lobe selection: give it with --select-lobes" in bad.stderr


def test_a_containing_form_starts_from_the_contained_forms_fits():
    from types import SimpleNamespace

    from brdfcl.optim.forms import nested_source, nesting_order, warm_start
    keys = ["gtr:dielectric", "ggx:dielectric", "gtr:schlick", "beckmann:schlick", "ggx:schlick"]
    order = sorted(keys, key=nesting_order)
    assert order.index("ggx:schlick") < order.index("gtr:schlick")
    assert order.index("ggx:dielectric") < order.index("gtr:dielectric")
    assert nested_source("gtr:schlick", {"ggx:schlick": []}) == "ggx:schlick"
    assert nested_source("gtr:schlick", {"ggx:dielectric": []}) is None       # another Fresnel: not contained
    assert nested_source("beckmann:schlick", {"ggx:schlick": []}) is None
    gtr = Model("diffuse+gtr:smith:schlick")
    fit = SimpleNamespace(params={n: 0.3 for n in Model("diffuse+ggx:smith:schlick").names})
    broken = SimpleNamespace(params={n: np.nan for n in Model("diffuse+ggx:smith:schlick").names})
    x = warm_start([fit, broken], gtr)
    gamma = gtr.names.index("ct.gamma")
    assert x.shape == (2, len(gtr.names)) and x[0, gamma] == 2.0
    assert np.all(np.delete(x[0], gamma) == 0.3)
    np.testing.assert_array_equal(x[1], gtr.defaults())                    # nothing usable: the defaults


def test_fit_all_refines_gtr_from_the_ggx_fits(demo_db, tmp_path):
    src, out = tmp_path / "in", tmp_path / "o"
    src.mkdir()
    (src / "synth-rough-metal.binary").symlink_to(demo_db / "synth-rough-metal.binary")   # Beckmann: no exact fit
    r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "fit-all", str(src), "--out", str(out),
                        "--select-lobes", "--forms", "gtr,ggx:schlick", "--no-report"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "form gtr:schlick: fitted 1 materials from the ggx:schlick fits" in r.stdout + r.stderr
    doc = json.loads((out / "synth-rough-metal.json").read_text())
    err = {k: v["rmse_log"] for k, v in doc["form_errors"].items()}
    assert err["ggx:schlick"] > 1e-4                                         # not at the float32 floor
    assert err["gtr:schlick"] <= err["ggx:schlick"] * (1 + 1e-3)            # contains it, starts at its optimum
