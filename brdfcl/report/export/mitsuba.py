"""A Mitsuba 3 BSDF plugin, ``"brdfcl"``, that renders a fitted model in every RGB variant.

Install the extra (``pip install "brdfcl[mitsuba]"``), choose an RGB variant, import this module
(it registers the plugin for the current variant and for every variant set later) and name a
fit result::

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")                  # or scalar_rgb, cuda_ad_rgb
    import brdfcl.report.export.mitsuba            # registers "brdfcl"
    bsdf = mi.load_dict({"type": "brdfcl", "fit": "fits/brass.json"})

``fit`` is what ``brdfcl fit-all --out DIR`` writes per material (``DIR/NAME.json``).  The BSDF
evaluates the fitted lobes with the functions printed from the terms' formulas in Dr.Jit
(brdfcl.report.export.drjit_model; the same formulas as the kernels and the float64 reference):
vectorised over a wavefront in the JIT variants (``llvm_ad_rgb``, ``cuda_ad_rgb``), per ray in the
scalar ones, and differentiable in the ``_ad_`` variants.  In the JIT variants the fitted
parameters are scene parameters, named as in NAME.json with ``.`` written ``_`` (``ct.alpha`` ->
``ct_alpha``)::

    params = mi.traverse(scene)
    key = "sphere.bsdf.ct_alpha"                   # SHAPE.bsdf.NAME, or BSDF_ID.NAME for a BSDF by id
    dr.enable_grad(params[key]); params.update()
    image = mi.render(scene, params)               # then dr.forward(params[key]), dr.grad(image)

Importance sampling is a mixture of cosine-weighted hemisphere sampling, the Cook-Torrance
lobe's NDF and a GGX stand-in for the diffraction lobe per channel (`brdfcl.report.export.sampling`
says how, and how the mixture weights are chosen, once, when the BSDF is made); the pdf is the
mixture's exact density.  The BSDF is one-sided (front side only, zero below the horizon) and
reflects only.  Spectral and monochrome variants need spectra the fit does not have: they are
refused with one line when the BSDF is made.
"""
from __future__ import annotations

try:
    import drjit as dr
    import mitsuba as mi
except ImportError as _e:  # pragma: no cover - depends on the environment
    raise ImportError(
        "brdfcl.report.export.mitsuba needs Mitsuba 3, which is not installed: "
        'pip install "brdfcl[mitsuba]"  (the mitsuba package from PyPI)') from _e

import warnings
from types import SimpleNamespace
from typing import Any

import numpy as np

from brdfcl._words import count
from brdfcl.report.export.drjit_model import DrjitModel, cells, ndf_density
from brdfcl.report.export.fitfile import load_fit
from brdfcl.report.export.sampling import Sampler, cosine_density, half_vector, half_vector_density

PLUGIN_NAME = "brdfcl"
LLVM_MIN = (17,)
"""Dr.Jit 1.5's LLVM kernels use llvm.minimum / llvm.maximum, which LLVM 16 and older cannot
compile for x86 ("Cannot select: fminimum", a crash of the whole process)."""
_U_MAX = 1.0 - 2.0 ** -24
"""The largest sample value used (1 - u stays positive in float32)."""
_registered: set = set()
_classes: dict = {}


def _check_variant():
    v = mi.variant()
    if v is None:
        raise RuntimeError("no Mitsuba variant is set: call mi.set_variant('llvm_ad_rgb') first")
    if not v.endswith("_rgb"):
        raise RuntimeError(f"the brdfcl BSDF renders a fit's R, G, B channels: it needs an RGB variant "
                           f"(llvm_ad_rgb, cuda_ad_rgb, scalar_rgb), not '{v}'")
    if v.startswith("llvm_") and _llvm_too_old():
        raise RuntimeError(_llvm_message())
    return v


def _llvm_too_old() -> bool:
    return tuple(dr.detail.llvm_version()) < LLVM_MIN


def _llvm_message() -> str:
    have = ".".join(map(str, dr.detail.llvm_version()))
    return (f"Dr.Jit's libLLVM {have} is too old for its kernels (needs {LLVM_MIN[0]}+): "
            f"apt install libllvm19, set DRJIT_LIBLLVM_PATH, or use scalar_rgb")


def _resolve(path: str) -> str:
    """A fit path as Mitsuba resolves files: relative to the scene file being loaded, then the
    working folder."""
    get: Any = getattr(mi, "file_resolver", None) or (lambda: mi.Thread.thread().file_resolver())
    resolver = get()
    return str(resolver.resolve(path))


def param_key(slot_name: str) -> str:
    """The scene parameter of a model parameter: ``ct.alpha`` -> ``ct_alpha``."""
    return slot_name.replace(".", "_")


_DR = SimpleNamespace(sqrt=dr.sqrt, log1p=lambda x: dr.log(1.0 + x), cos=dr.cos, sin=dr.sin)
"""The functions `half_vector` draws with, in Dr.Jit (which has no log1p: 1 - u is exact in float32
for the u Mitsuba's samplers give)."""


def _half_vector(kind, alpha, u, v):
    u = dr.select(u < _U_MAX, u, _U_MAX)
    return mi.Vector3f(*half_vector(kind, alpha, u, v, _DR))


def bsdf_class():
    """The plugin's class for the current variant (Mitsuba's BSDF base class is per variant)."""
    v = mi.variant()
    if v is None:
        raise RuntimeError("no Mitsuba variant is set: call mi.set_variant('llvm_ad_rgb') first")
    if v in _classes:
        return _classes[v]

    class BrdfclBSDF(mi.BSDF):
        """The fitted model of one ``NAME.json`` as a reflective, front-sided BSDF."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            _check_variant()
            if "fit" not in props:
                raise ValueError('the brdfcl BSDF needs "fit": the path of a fit-all NAME.json')
            self.fit_path = str(props["fit"])
            fit = load_fit(_resolve(self.fit_path))
            if fit.model.n_channels != 3:
                raise ValueError(f"{self.fit_path}: a fit of {count(fit.model.n_channels, 'channel')}; the "
                                 f"brdfcl BSDF renders fits of 3 (R, G, B)")
            self.material = fit.name
            self.model = DrjitModel(fit.model, fit.values, mi.Float)
            self.sampler = Sampler(fit.model, fit.values)
            comps = self.sampler.components
            self._comps = [(c.kind, float(c.alpha), float(c.weight)) for c in comps]
            self._cum = [float(x) for x in np.cumsum([c.weight for c in comps])]
            diffuse = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            glossy = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            # component 0: the cosine-weighted part (diffuse lobe), 1: the half-vector lobes
            self.m_components = [diffuse, glossy]
            self.m_flags = diffuse | glossy

        # Mitsuba's interface: wi = si.wi (towards the viewer), wo towards the light, local frame;
        # eval returns f(wi, wo) cos(theta_o).
        def _eval(self, c, valid, wo, active):
            f = self.model.brdf_cells(c)
            f = mi.Color3f(f[0], f[1], f[2]) * wo.z
            return dr.select(active & valid, f, 0.0)

        def _pdf(self, c, valid, wo, active):
            # wo.h is cos theta_d, as wi.h is: the cells hold it
            total = 0.0
            for kind, alpha, weight in self._comps:
                if kind == "cosine":
                    p = cosine_density(wo.z)
                else:
                    D = ndf_density(kind, alpha, c.ch, c.t2)
                    p = dr.select(c.cd > 0, half_vector_density(D, c.ch, dr.select(c.cd > 0, c.cd, 1.0)), 0.0)
                total = total + weight * p
            return dr.select(active & valid, total, 0.0)

        def eval(self, ctx, si, wo, active=True):
            c, valid = cells(si.wi, wo)
            return self._eval(c, valid, wo, active)

        def pdf(self, ctx, si, wo, active=True):
            c, valid = cells(si.wi, wo)
            return self._pdf(c, valid, wo, active)

        def eval_pdf(self, ctx, si, wo, active=True):
            c, valid = cells(si.wi, wo)
            return self._eval(c, valid, wo, active), self._pdf(c, valid, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wi = si.wi
            wo = mi.warp.square_to_cosine_hemisphere(sample2)
            glossy = mi.Bool(False)
            for j, (kind, alpha, _) in enumerate(self._comps[1:], start=1):
                h = _half_vector(kind, alpha, sample2.x, sample2.y)
                reflected = 2.0 * dr.dot(wi, h) * h - wi
                take = sample1 >= self._cum[j - 1]
                wo = dr.select(take, reflected, wo)
                glossy = glossy | take
            f, pdf = self.eval_pdf(ctx, si, wo, active)
            valid = active & (pdf > 0) & (wi.z > 0) & (wo.z > 0)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = wo
            bs.pdf = dr.select(valid, pdf, 0.0)
            bs.eta = 1.0
            bs.sampled_component = dr.select(glossy, mi.UInt32(1), mi.UInt32(0))
            bs.sampled_type = dr.select(glossy, mi.UInt32(+mi.BSDFFlags.GlossyReflection),
                                        mi.UInt32(+mi.BSDFFlags.DiffuseReflection))
            return bs, dr.select(valid, f / dr.select(valid, pdf, 1.0), 0.0)

        def traverse(self, callback):
            # Mitsuba can update a plugin's parameter in place only when it is a Dr.Jit array: in the
            # scalar variants they are Python floats, so they are not scene parameters there
            if dr.is_array_v(mi.Float):
                for name, value in self.model.params.items():
                    callback.put(param_key(name), value, mi.ParamFlags.Differentiable)

        def parameters_changed(self, keys=None):
            self.model.update()

        def to_string(self):
            return (f"BrdfclBSDF[\n  fit = \"{self.fit_path}\",\n  model = {self.model.model.spec},\n"
                    f"  sampling = {self.sampler.describe()}\n]")

    _classes[v] = BrdfclBSDF
    return BrdfclBSDF


def register():
    """Register the ``"brdfcl"`` BSDF with Mitsuba for the current variant (idempotent).

    Importing this module does it for the variant set then and for every variant set later."""
    v = mi.variant()
    if v is None:
        raise RuntimeError("no Mitsuba variant is set: call mi.set_variant('llvm_ad_rgb') first")
    if v not in _registered:
        cls = bsdf_class()
        mi.register_bsdf(PLUGIN_NAME, lambda props: cls(props))
        _registered.add(v)


def _on_variant_change(old=None, new=None):
    # Registered in any variant: making the BSDF in one it does not support says why.  A failure
    # here must not break mi.set_variant; register() called directly shows it.  An LLVM that
    # cannot compile Dr.Jit's kernels aborts the process at the first render, of any scene: say so
    # now, in one line.
    try:
        v = mi.variant()
        if v is not None:
            register()
            if v.startswith("llvm_") and _llvm_too_old():
                warnings.warn(_llvm_message(), RuntimeWarning, stacklevel=2)
    except Exception:  # pragma: no cover
        pass


_on_variant_change()
if hasattr(mi, "detail") and hasattr(mi.detail, "add_variant_callback"):
    mi.detail.add_variant_callback(_on_variant_change)
