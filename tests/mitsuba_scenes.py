"""What the Mitsuba 3 tests share: a variant with the plugin registered (or a skip saying why
not), and the sphere under a directional light they render BSDFs on."""
import numpy as np
import pytest

LIGHT = np.array([-0.5, 0.6, 0.62]) / np.linalg.norm([-0.5, 0.6, 0.62])
"""Direction towards the key light of the test renders."""


def use_variant(variant):
    """Mitsuba in ``variant`` with the "brdfcl" BSDF registered, or a skip: without the extra,
    without the variant (llvm_*: no libLLVM found), or with a libLLVM too old for Dr.Jit."""
    mi = pytest.importorskip("mitsuba", reason='Mitsuba 3 not installed: pip install "brdfcl[mitsuba]"')
    try:
        mi.set_variant(variant)
    except Exception as e:
        pytest.skip(f"Mitsuba variant {variant} unavailable here: {str(e).splitlines()[0]}")
    import brdfcl.report.export.mitsuba as plugin
    if variant.startswith("llvm_"):
        import drjit as dr
        have = tuple(dr.detail.llvm_version())
        if have < plugin.LLVM_MIN:
            pytest.skip(f"Dr.Jit loaded libLLVM {have}, too old for its kernels (Debian 12: apt install libllvm19)")
    return mi


def sphere_scene(mi, bsdf, size, spp, emitter=None, integrator=None, sampler="stratified", rfilter="box"):
    """A unit sphere filling an orthographic view along -z, by default under a directional light of
    unit irradiance from LIGHT with emitter sampling alone: radiance f(wi, wo) max(0, n.wi)."""
    return mi.load_dict({
        "type": "scene",
        "integrator": integrator or {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": {"type": "orthographic",           # [-1, 1]^2 of the view plane: the unit sphere fills it
                   "to_world": mi.ScalarTransform4f.look_at(origin=[0, 0, 3], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": rfilter},
                            "pixel_format": "rgb"},
                   "sampler": {"type": sampler, "sample_count": spp, "seed": 5}},
        "sphere": {"type": "sphere", "bsdf": bsdf},
        "light": emitter or {"type": "directional", "direction": (-LIGHT).tolist(),
                             "irradiance": {"type": "rgb", "value": 1.0}}})


def render(mi, scene, **kwargs):
    return np.array(mi.render(scene, **kwargs), dtype=np.float64)


def relative_difference(a, b):
    """|b - a| / a over the pixels a lights (above 1e-6 of its largest)."""
    lit = a > 1e-6 * a.max()
    return np.abs(b[lit] - a[lit]) / a[lit], lit


def disc(size):
    """Each pixel centre's normal on the unit sphere of `sphere_scene` (size, size, 3), and its
    distance from the centre of the view."""
    c = (np.arange(size) + 0.5) / size * 2 - 1
    x, y = np.meshgrid(c, -c)                      # row 0 at the top, y up (as brdfcl.report.view.sphere)
    r2 = x * x + y * y
    return np.stack([x, y, np.sqrt(np.clip(1 - r2, 0, 1))], -1), np.sqrt(r2)
