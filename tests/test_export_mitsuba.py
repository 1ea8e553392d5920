"""The Mitsuba 3 BSDF of a fitted model (brdfcl.report.export.mitsuba), rendered with scalar_rgb.

Skips with a reason without the extra (pip install "brdfcl[mitsuba]").  The material is the demo
database's smooth metal (diffuse + diffraction + GGX, its known parameters written as a fit
result), the lobe mix that exercises every sampling component."""
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

NAME = "synth-smooth-metal"
LIGHT = np.array([-0.5, 0.6, 0.62]) / np.linalg.norm([-0.5, 0.6, 0.62])


@pytest.fixture(scope="module")
def mi():
    mi = pytest.importorskip("mitsuba", reason='Mitsuba 3 not installed: pip install "brdfcl[mitsuba]"')
    mi.set_variant("scalar_rgb")
    import brdfcl.report.export.mitsuba  # noqa: F401  (registers "brdfcl")
    return mi


@pytest.fixture(scope="module")
def fit(tmp_path_factory):
    spec, params = DEMO[NAME]
    model = Model(spec)
    values = demo_values(model, params)
    path = tmp_path_factory.mktemp("fit") / f"{NAME}.json"
    path.write_text(json.dumps(fit_document(model, values, NAME)))
    return model, values, path


def _scene(mi, path, size, spp, emitter, integrator, sampler="stratified"):
    return mi.load_dict({
        "type": "scene", "integrator": integrator,
        "sensor": {"type": "orthographic",           # [-1, 1]^2 of the view plane: the unit sphere fills it
                   "to_world": mi.ScalarTransform4f.look_at(origin=[0, 0, 3], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"},
                            "pixel_format": "rgb"},
                   "sampler": {"type": sampler, "sample_count": spp, "seed": 5}},
        "sphere": {"type": "sphere", "bsdf": {"type": "brdfcl", "fit": str(path)}},
        "light": emitter})


def _disc(size):
    c = (np.arange(size) + 0.5) / size * 2 - 1
    x, y = np.meshgrid(c, -c)                      # row 0 at the top, y up (as brdfcl.report.view.sphere)
    r2 = x * x + y * y
    return np.stack([x, y, np.sqrt(np.clip(1 - r2, 0, 1))], -1), np.sqrt(r2)


@pytest.mark.slow
def test_sphere_matches_brdfcl_rendering(mi, fit):
    """Directional light of unit irradiance: radiance f(wi, wo) max(0, n.wi) per pixel."""
    from brdfcl.report.view.sphere import render_model_sphere
    model, values, path = fit
    size = 48
    scene = _scene(mi, path, size, 16,
                   {"type": "directional", "direction": (-LIGHT).tolist(),
                    "irradiance": {"type": "rgb", "value": 1.0}},
                   {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0})
    img = np.array(mi.render(scene))
    ref = render_model_sphere(model, values, LIGHT, size=size)
    n, r = _disc(size)
    # Mitsuba averages each pixel (box filter), brdfcl takes its centre: leave out the silhouette
    # and the terminator, where the two differ by the pixel's footprint
    mask = (r < 1 - 2.0 / size) & (n @ LIGHT > 0.05) & np.isfinite(ref).all(-1)
    rel = np.abs(img[mask] - ref[mask]) / ref[mask]
    med, p90 = np.median(rel), np.percentile(rel, 90)
    print(f"\nmitsuba vs brdfcl sphere, {mask.sum()} pixels x 3: median relative difference {med:.4f}, "
          f"90th percentile {p90:.4f}")
    # measured: median 0.0043, 90th percentile 0.012 (the highlight's few pixels differ most)
    assert med < 0.015 and p90 < 0.05
    assert np.all(img[r > 1 + 2.0 / size] == 0)              # nothing off the sphere


@pytest.mark.slow
def test_bsdf_sampling_in_mitsuba_gives_the_albedo(mi, fit):
    """Constant environment of radiance 1, directions from the BSDF's sample() alone: each pixel
    is the directional albedo of its view angle, computed here from brdfcl's Model.reference."""
    model, values, path = fit
    size = 24
    scene = _scene(mi, path, size, 16, {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
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
    n, r = _disc(size)
    mask = (r < 1 - 2.0 / size) & (n[..., 2] > cz[0])
    expect = np.stack([np.interp(n[..., 2][mask], cz, albedo[:, k]) for k in range(3)], -1)
    ratio = img[mask].mean(axis=0) / expect.mean(axis=0)
    print(f"\nmitsuba BSDF-sampled albedo / expected, disc mean: {np.round(ratio, 4)}")
    assert np.all(np.abs(ratio - 1) < 0.03)


def test_bsdf_methods_agree_with_the_model(mi, fit):
    model, values, path = fit
    bsdf = mi.load_dict({"type": "brdfcl", "fit": str(path)})
    assert "diffraction" in str(bsdf)
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    rng = np.random.default_rng(3)
    sm = Sampler(model, values)
    for _ in range(20):
        wi = rng.normal(size=3)
        wi[2] = abs(wi[2])
        wi /= np.linalg.norm(wi)
        si.wi = mi.Vector3f(*wi)
        wi = np.array(si.wi, dtype=np.float64)          # as Mitsuba holds it (float32)
        bs, w = bsdf.sample(ctx, si, float(rng.random()), mi.Point2f(*rng.random(2)))
        wo = np.array(bs.wo)
        if bs.pdf == 0:
            continue
        f = model.reference(Cells.from_directions(wi[None], wo[None]), values, jacobian=False)[:, 0]
        ev = np.array(bsdf.eval(ctx, si, bs.wo))
        np.testing.assert_allclose(ev, f * wo[2], rtol=1e-5)
        e2, p2 = bsdf.eval_pdf(ctx, si, bs.wo)
        assert float(bsdf.pdf(ctx, si, bs.wo)) == pytest.approx(float(p2), rel=1e-5)
        # bs.wo is stored in float32: near a sharp peak the pdf there differs by ~1e-5
        assert float(bs.pdf) == pytest.approx(float(sm.pdf(wi[None], wo[None])[0]), rel=1e-3)
        np.testing.assert_allclose(np.array(w), ev / float(bs.pdf), rtol=1e-3)
    # below the horizon: nothing
    si.wi = mi.Vector3f(0.0, 0.6, 0.8)
    assert np.all(np.array(bsdf.eval(ctx, si, mi.Vector3f(0.0, 0.0, -1.0))) == 0)


def test_missing_fit_is_a_clear_error(mi, tmp_path):
    with pytest.raises(Exception, match="fit"):
        mi.load_dict({"type": "brdfcl"})
    with pytest.raises(Exception, match="cannot read fit result"):
        mi.load_dict({"type": "brdfcl", "fit": str(tmp_path / "nope.json")})


def test_without_mitsuba_the_import_says_how_to_install():
    code = ("import sys; sys.modules['mitsuba'] = None; sys.modules['drjit'] = None\n"
            "try:\n    import brdfcl.report.export.mitsuba\nexcept ImportError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert 'pip install "brdfcl[mitsuba]"' in out.stdout, out.stdout + out.stderr
    # the package itself never imports Mitsuba
    code = "import sys, brdfcl.report.export, brdfcl.report.export.brdf_explorer; print('mitsuba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "False", out.stdout + out.stderr
