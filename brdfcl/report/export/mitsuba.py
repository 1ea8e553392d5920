"""A Mitsuba 3 BSDF plugin, ``"brdfcl"``, that renders a fitted model.

Install the extra (``pip install "brdfcl[mitsuba]"``), choose a scalar RGB variant, import this
module (it registers the plugin for the current variant and for every variant set later) and
name a fit result::

    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    import brdfcl.report.export.mitsuba            # registers "brdfcl"; or brdfcl.report.export.mitsuba.register()
    bsdf = mi.load_dict({"type": "brdfcl", "fit": "fits/brass.json"})

``fit`` is what ``brdfcl fit-all --out DIR`` writes per material (``DIR/NAME.json``).  The BSDF
evaluates the fitted lobes with brdfcl's float64 reference (``Model.reference``, the formulas the
fit used) and importance-samples them with a mixture of cosine-weighted hemisphere sampling,
the Cook-Torrance lobe's NDF and a GGX stand-in for the diffraction lobe per channel
(`brdfcl.report.export.sampling` says how, and how the mixture weights are chosen).  It is one-sided
(front side only, zero below the horizon) and reflects only.

The evaluation runs in numpy, one call per ray: variants ``scalar_rgb`` (tested) and
``scalar_rgb_double`` where built.  JIT variants (``llvm_*``, ``cuda_*``) trace the plugin
symbolically and spectral variants need spectra the fit does not have: they are refused with
one line when the BSDF is made.
"""
from __future__ import annotations

try:
    import drjit as dr  # noqa: F401  (mitsuba needs it; imported for a clear error)
    import mitsuba as mi
except ImportError as _e:  # pragma: no cover - depends on the environment
    raise ImportError(
        "brdfcl.report.export.mitsuba needs Mitsuba 3, which is not installed: "
        'pip install "brdfcl[mitsuba]"  (the mitsuba package from PyPI)') from _e

import numpy as np

from brdfcl.report.export.fitfile import load_fit
from brdfcl.report.export.sampling import Sampler

PLUGIN_NAME = "brdfcl"
_registered: set = set()


def _check_variant():
    v = mi.variant()
    if v is None:
        raise RuntimeError("no Mitsuba variant is set: call mi.set_variant('scalar_rgb') first")
    if not (v.startswith("scalar_") and "rgb" in v and "polarized" not in v):
        raise RuntimeError(f"the brdfcl BSDF evaluates the fit in numpy, one ray at a time: it "
                           f"needs a scalar RGB variant (scalar_rgb), not '{v}'")
    return v


def _vec(v):
    return np.array([float(v[0]), float(v[1]), float(v[2])])[None, :]


def _color(x):
    return mi.Color3f(float(x[0]), float(x[1]), float(x[2]))


_classes: dict = {}


def bsdf_class():
    """The plugin's class for the current variant (Mitsuba's BSDF base class is per variant)."""
    v = mi.variant()
    if v is None:
        raise RuntimeError("no Mitsuba variant is set: call mi.set_variant('scalar_rgb') first")
    if v in _classes:
        return _classes[v]

    class BrdfclBSDF(mi.BSDF):
        """The fitted model of one ``NAME.json`` as a reflective, front-sided BSDF."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            _check_variant()
            try:
                has_fit = "fit" in props
            except TypeError:                    # Mitsuba before 3.6
                has_fit = props.has_property("fit")
            if not has_fit:
                raise ValueError('the brdfcl BSDF needs "fit": the path of a fit-all NAME.json')
            self.fit_path = str(props["fit"])
            fit = load_fit(self.fit_path)
            self.model, self.values, self.material = fit.model, fit.values, fit.name
            self.sampler = Sampler(self.model, self.values)
            diffuse = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            glossy = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            # component 0: the cosine-weighted part (diffuse lobe), 1: the half-vector lobes
            self.m_components = [diffuse, glossy]
            self.m_flags = diffuse | glossy
            self._types = (int(mi.BSDFFlags.DiffuseReflection), int(mi.BSDFFlags.GlossyReflection))

        # Mitsuba's interface: wi = si.wi (towards the viewer), wo towards the light, local frame;
        # eval returns f(wi, wo) cos(theta_o).
        def eval(self, ctx, si, wo, active=True):
            if not active:
                return mi.Color3f(0.0)
            return _color(self.sampler.eval(_vec(si.wi), _vec(wo))[:, 0])

        def pdf(self, ctx, si, wo, active=True):
            if not active:
                return 0.0
            return float(self.sampler.pdf(_vec(si.wi), _vec(wo))[0])

        def eval_pdf(self, ctx, si, wo, active=True):
            if not active:
                return mi.Color3f(0.0), 0.0
            f, p = self.sampler.eval_pdf(_vec(si.wi), _vec(wo))
            return _color(f[:, 0]), float(p[0])

        def sample(self, ctx, si, sample1, sample2, active=True):
            bs = mi.BSDFSample3f()
            if not active:
                return bs, mi.Color3f(0.0)
            wo, p, w, k = self.sampler.sample(_vec(si.wi), [float(sample1)],
                                              [[float(sample2[0]), float(sample2[1])]])
            if p[0] <= 0:
                return bs, mi.Color3f(0.0)      # pdf 0: an invalid sample, as Mitsuba's BSDFs do
            comp = 0 if self.sampler.components[int(k[0])].kind == "cosine" else 1
            bs.wo = mi.Vector3f(float(wo[0, 0]), float(wo[0, 1]), float(wo[0, 2]))
            bs.pdf = float(p[0])
            bs.eta = 1.0
            bs.sampled_component = comp
            bs.sampled_type = self._types[comp]
            return bs, _color(w[:, 0])

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys=None):
            pass

        def to_string(self):
            return (f"BrdfclBSDF[\n  fit = \"{self.fit_path}\",\n  model = {self.model.spec},\n"
                    f"  sampling = {self.sampler.describe()}\n]")

    _classes[v] = BrdfclBSDF
    return BrdfclBSDF


def register():
    """Register the ``"brdfcl"`` BSDF with Mitsuba for the current variant (idempotent).

    Importing this module does it for the variant set then and for every variant set later."""
    v = mi.variant()
    if v is None:
        raise RuntimeError("no Mitsuba variant is set: call mi.set_variant('scalar_rgb') first")
    if v not in _registered:
        cls = bsdf_class()
        mi.register_bsdf(PLUGIN_NAME, lambda props: cls(props))
        _registered.add(v)


def _on_variant_change(old=None, new=None):
    # Registered in any variant: making the BSDF in one it does not support says why.  A failure
    # here must not break mi.set_variant; register() called directly shows it.
    try:
        if mi.variant() is not None:
            register()
    except Exception:  # pragma: no cover
        pass


_on_variant_change()
if hasattr(mi, "detail") and hasattr(mi.detail, "add_variant_callback"):
    mi.detail.add_variant_callback(_on_variant_change)
