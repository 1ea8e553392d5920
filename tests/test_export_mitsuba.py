"""The Mitsuba 3 BSDF of a fitted model (brdfcl.report.export.mitsuba), in scalar_rgb and llvm_ad_rgb.

Skips with a reason without the extra (pip install "brdfcl[mitsuba]"), and in llvm_ad_rgb where
Dr.Jit finds no libLLVM or one too old to compile its kernels.  The material is the demo
database's smooth metal (diffuse + diffraction + GGX, its known parameters written as a fit
result), the lobe mix that exercises every sampling component; the gradient tests add a GTR lobe,
whose normalisation and Smith series are host constants."""
import json
import subprocess
import sys

import numpy as np
import pytest

from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.synth import DEMO, demo_values
from brdfcl.report.export.fitfile import fit_document
from brdfcl.report.export.sampling import Sampler
from tests.mitsuba_scenes import LIGHT, disc, sphere_scene, use_variant

# -n with --dist loadgroup (the slow tier in .ci/run): one process runs this module's tests, not
# one after another, so its costly fixture is session-scoped: made once there
pytestmark = pytest.mark.xdist_group("test_export_mitsuba")

NAME = "synth-smooth-metal"
VARIANTS = ["scalar_rgb", "llvm_ad_rgb"]


@pytest.fixture(params=VARIANTS)
def mi(request):
    return use_variant(request.param)


@pytest.fixture
def mi_llvm():
    return use_variant("llvm_ad_rgb")


def _write_fit(path, spec, values, name="x"):
    model = Model(spec)
    path.write_text(json.dumps(fit_document(model, values, name)))
    return model, np.asarray(values, dtype=np.float64), path


@pytest.fixture(scope="session")
def fit(tmp_path_factory):
    spec, params = DEMO[NAME]
    model = Model(spec)
    return _write_fit(tmp_path_factory.mktemp("fit") / f"{NAME}.json", spec, demo_values(model, params), NAME)


def _directions(n, seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(2, n, 3))
    v[..., 2] = np.abs(v[..., 2])
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    # half of the pairs near the specular peak, where the sharp lobes are
    m = n // 2
    v[1, :m] = np.array([-1, -1, 1]) * v[0, :m] + 0.02 * rng.normal(size=(m, 3))
    v[1, :m, 2] = np.abs(v[1, :m, 2])
    v[1, :m] /= np.linalg.norm(v[1, :m], axis=-1, keepdims=True)
    v = v[:, (v[0, :, 2] > 0.02) & (v[1, :, 2] > 0.02)]
    return v[0].astype(np.float32).astype(np.float64), v[1].astype(np.float32).astype(np.float64)


def _eval(mi, bsdf, wi, wo):
    """(eval, pdf) of a BSDF at direction pairs, as float64 (3, n) and (n,)."""
    import drjit as dr
    ctx = mi.BSDFContext()
    if dr.is_array_v(mi.Float):
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(wi.T)
        f, p = bsdf.eval_pdf(ctx, si, mi.Vector3f(wo.T))
        return np.array(f, dtype=np.float64).reshape(3, -1), np.array(p, dtype=np.float64).ravel()
    fs, ps = [], []
    si = mi.SurfaceInteraction3f()
    for a, b in zip(wi, wo):
        si.wi = mi.Vector3f(*map(float, a))
        f, p = bsdf.eval_pdf(ctx, si, mi.Vector3f(*map(float, b)))
        fs.append(np.array(f, dtype=np.float64))
        ps.append(float(p))
    return np.array(fs).T, np.array(ps)


def test_eval_and_pdf_agree_with_the_float64_reference(mi, fit):
    model, values, path = fit
    bsdf = mi.load_dict({"type": "brdfcl", "fit": str(path)})
    assert "diffraction" in str(bsdf)
    n = 4000 if mi.variant().startswith("llvm") else 300
    wi, wo = _directions(n, 3)
    f, p = _eval(mi, bsdf, wi, wo)
    ref = model.reference(Cells.from_directions(wi, wo), values, jacobian=False) * wo[:, 2]
    rel = np.abs(f - ref) / np.abs(ref)
    print(f"\n{mi.variant()}: eval vs float64 reference, {n} pairs: largest relative difference {rel.max():.2e}")
    assert rel.max() < 2e-5                     # float32 directions and arithmetic in both variants
    expect = Sampler(model, values).pdf(wi, wo)
    np.testing.assert_allclose(p, expect, rtol=2e-4)


def test_sampled_directions_carry_eval_over_pdf(mi, fit):
    model, values, path = fit
    bsdf = mi.load_dict({"type": "brdfcl", "fit": str(path)})
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    rng = np.random.default_rng(3)
    kept = 0
    for _ in range(30):
        wi = rng.normal(size=3)
        wi[2] = abs(wi[2])
        si.wi = mi.Vector3f(*map(float, wi / np.linalg.norm(wi)))
        bs, w = bsdf.sample(ctx, si, float(rng.random()), mi.Point2f(*map(float, rng.random(2))))
        if float(np.ravel(bs.pdf)[0]) == 0:
            continue
        kept += 1
        ev, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
        assert float(np.ravel(bs.pdf)[0]) == pytest.approx(float(np.ravel(pdf)[0]), rel=1e-5)
        np.testing.assert_allclose(np.ravel(w), np.ravel(ev) / float(np.ravel(pdf)[0]), rtol=1e-4)
    assert kept > 20
    si.wi = mi.Vector3f(0.0, 0.6, 0.8)             # below the horizon: nothing
    assert np.all(np.array(bsdf.eval(ctx, si, mi.Vector3f(0.0, 0.0, -1.0))) == 0)


def _sphere_difference(mi, model, values, img):
    from brdfcl.report.view.sphere import render_model_sphere
    size = img.shape[0]
    ref = render_model_sphere(model, values, LIGHT, size=size)
    n, r = disc(size)
    # Mitsuba averages each pixel (box filter), brdfcl takes its centre: leave out the silhouette
    # and the terminator, where the two differ by the pixel's footprint
    mask = (r < 1 - 2.0 / size) & (n @ LIGHT > 0.05) & np.isfinite(ref).all(-1)
    rel = np.abs(img[mask] - ref[mask]) / ref[mask]
    assert np.all(img[r > 1 + 2.0 / size] == 0)              # nothing off the sphere
    return np.median(rel), np.percentile(rel, 90)


def test_llvm_sphere_matches_brdfcl_rendering(mi_llvm, fit):
    """Directional light of unit irradiance: radiance f(wi, wo) max(0, n.wi) per pixel."""
    mi = mi_llvm
    model, values, path = fit
    img = np.array(mi.render(sphere_scene(mi, {"type": "brdfcl", "fit": str(path)}, 64, 16)))
    med, p90 = _sphere_difference(mi, model, values, img)
    print(f"\nllvm_ad_rgb vs brdfcl sphere, 64 x 64, 16 spp: median relative difference {med:.5f}, 90th pct {p90:.4f}")
    assert med < 0.005


@pytest.mark.slow
def test_scalar_sphere_matches_brdfcl_rendering(fit):
    mi = use_variant("scalar_rgb")
    model, values, path = fit
    img = np.array(mi.render(sphere_scene(mi, {"type": "brdfcl", "fit": str(path)}, 48, 16)))
    med, p90 = _sphere_difference(mi, model, values, img)
    print(f"\nscalar_rgb vs brdfcl sphere, 48 x 48, 16 spp: median relative difference {med:.5f}, 90th pct {p90:.4f}")
    assert med < 0.005


@pytest.mark.parametrize("spec, key", [
    ("diffuse+diffraction:hp+ggx:smith:conductor", "ct.alpha"),
    ("diffuse+diffraction:hp+ggx:smith:conductor", "diffraction.a"),
    ("diffuse+gtr:smith:dielectric", "ct.gamma"),           # through the host constants K, c0..c13
    ("diffuse+gtr:smith:dielectric", "ct.eta"),
])
def test_render_gradient_agrees_with_finite_differences(mi_llvm, tmp_path, spec, key):
    """dr.grad of a rendered image (forward mode) against central differences of two renders.
    The differences are taken at the seed of the gradient pass, so both see the same pixels'
    sample positions; a directional light makes the render otherwise deterministic."""
    import drjit as dr

    from brdfcl.report.export.mitsuba import param_key
    mi = mi_llvm
    model = Model(spec)
    _, _, path = _write_fit(tmp_path / "f.json", spec, model.defaults())
    scene = sphere_scene(mi, {"type": "brdfcl", "fit": str(path)}, 48, 4, integrator={"type": "prb", "max_depth": 2})
    params = mi.traverse(scene)
    k = "sphere.bsdf." + param_key(key)
    x0 = float(params[k][0])
    dr.enable_grad(params[k])
    params.update()
    img = mi.render(scene, params, seed=1, seed_grad=2)
    dr.forward(params[k])
    grad = float(np.sum(np.array(dr.grad(img), dtype=np.float64)))
    dr.disable_grad(params[k])
    h = 1e-3 * abs(x0)

    def total(x):
        params[k] = mi.Float(x)
        params.update()
        return float(np.sum(np.array(mi.render(scene, params, seed=2), dtype=np.float64)))
    fd = (total(x0 + h) - total(x0 - h)) / (2 * h)
    print(f"\n{spec} d/d {key}: AD {grad:.6g}, finite differences {fd:.6g}")
    assert grad == pytest.approx(fd, rel=5e-3)


@pytest.mark.slow
def test_bsdf_sampling_in_mitsuba_gives_the_albedo(mi_llvm, fit):
    """Constant environment of radiance 1, directions from the BSDF's sample() alone: each pixel
    is the directional albedo of its view angle, computed here from brdfcl's Model.reference."""
    mi = mi_llvm
    model, values, path = fit
    size = 32
    scene = sphere_scene(mi, {"type": "brdfcl", "fit": str(path)}, size, 256,
                         {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
                         {"type": "direct", "emitter_samples": 0, "bsdf_samples": 1, "hide_emitters": True},
                         sampler="independent")
    img = np.array(mi.render(scene))
    sm = Sampler(model, values)
    rng = np.random.default_rng(0)
    cz = np.linspace(0.05, 1.0, 20)
    albedo = []
    for c in cz:
        wi = np.broadcast_to([np.sqrt(1 - c * c), 0.0, c], (40000, 3))
        _, _, w, _ = sm.sample(wi, rng.random(len(wi)), rng.random((len(wi), 2)))
        albedo.append(w.mean(axis=1))
    albedo = np.array(albedo)
    n, r = disc(size)
    mask = (r < 1 - 2.0 / size) & (n[..., 2] > cz[0])
    expect = np.stack([np.interp(n[..., 2][mask], cz, albedo[:, k]) for k in range(3)], -1)
    ratio = img[mask].mean(axis=0) / expect.mean(axis=0)
    print(f"\nmitsuba BSDF-sampled albedo / expected, disc mean: {np.round(ratio, 4)}")
    assert np.all(np.abs(ratio - 1) < 0.02)


def test_missing_fit_and_other_variants_are_clear_errors(tmp_path, fit):
    mi = use_variant("scalar_rgb")
    with pytest.raises(Exception, match="fit"):
        mi.load_dict({"type": "brdfcl"})
    with pytest.raises(Exception, match="cannot read fit result"):
        mi.load_dict({"type": "brdfcl", "fit": str(tmp_path / "nope.json")})
    mi.set_variant("scalar_spectral")
    try:
        with pytest.raises(Exception, match="needs an RGB variant"):
            mi.load_dict({"type": "brdfcl", "fit": str(fit[2])})
    finally:
        mi.set_variant("scalar_rgb")


def test_without_mitsuba_the_import_says_how_to_install():
    code = ("import sys; sys.modules['mitsuba'] = None; sys.modules['drjit'] = None\n"
            "try:\n    import brdfcl.report.export.mitsuba\nexcept ImportError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert 'pip install "brdfcl[mitsuba]"' in out.stdout, out.stdout + out.stderr
    # the package itself never imports Mitsuba
    code = ("import sys, brdfcl.report.export, brdfcl.report.export.brdf_explorer, "
            "brdfcl.report.export.mitsuba_scene, brdfcl.report.writers; print('mitsuba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "False", out.stdout + out.stderr
