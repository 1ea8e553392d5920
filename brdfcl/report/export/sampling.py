"""Evaluation and importance sampling of a fitted model in a local shading frame (n = z).

Renderers need, besides the BRDF, a way to draw outgoing directions and the density of that
draw.  This is a mixture, one component per lobe (per channel for diffraction):

* ``diffuse``: cosine-weighted hemisphere, pdf = cos(theta_o) / pi.  It is always present, with
  at least `DEFENSIVE` of the weight, so that the pdf is positive wherever the BRDF is.
* Cook-Torrance: half-vectors drawn from the lobe's NDF times cos(theta_h) (GGX and Beckmann
  exactly, with the fitted alpha), reflected about the incident direction:
  pdf(wo) = D(h) cos(theta_h) / (4 wo.h).  SGD and EPD have no closed-form sampling: a GGX whose
  half maximum (in tan^2 theta_h) is the fitted NDF's stands in for them.
* diffraction: the lobe is S(f_c), f_c = 2 sin(theta_h) cos(theta_d) / lambda_c.  Near the peak
  (cos theta_d ~ 1) the ``hp`` PSD, 1 / (1 + f^2/a^2)^2, is a GGX in sin(theta_h) with
  alpha = lambda_c a / 2, so each channel gets a GGX half-vector component whose half maximum is
  that of the PSD (exactly alpha = lambda_c a / 2 at small angles for ``hp``; the same rule
  for ``abc`` and ``gauss``).  This is an approximation of the lobe's shape used only to choose
  directions; the pdf returned is the exact density of the mixture, so estimates stay unbiased.

Mixture weights are the components' directional albedos (mean over channels, and over incidence
angles 0, 30 and 60 degrees), estimated once at construction with each component's own sampling
on a fixed low-discrepancy set (deterministic).  Half-vectors that reflect below the horizon are
lost samples (pdf 0, weight 0), as in Mitsuba's own microfacet BSDFs: the pdf integrates over the
upper hemisphere to the fraction of samples that are kept (close to 1 except for broad lobes at
grazing incidence).

Everything is vectorised over directions: ``wi`` and ``wo`` are (n, 3) arrays, unit length, in the
local frame; ``wi`` is the direction towards the viewer (Mitsuba's ``si.wi``), ``wo`` towards the
light.  The BRDF is reciprocal, so the roles may be swapped.

About 300 lines, one module: the components' draws, their densities and the mixture weights
estimated from those draws are one sampler, checked together (tests/test_export_sampling.py).
The Mitsuba 3 BSDF (brdfcl.report.export.mitsuba) takes its components and weights from here and
draws with the same rules (`half_vector`, `half_vector_density`, `cosine_density`) in Dr.Jit;
this numpy sampler is their float64 reference.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from brdfcl.data.sobol import sobol_points
from brdfcl.model.compose import Model
from brdfcl.model.lobes import REGISTRY
from brdfcl.model.lobes.cells import Cells

DEFENSIVE = 0.05
"""Smallest weight of the cosine-weighted (diffuse) component."""
ALPHA_RANGE = (1e-4, 2.0)
"""Proposal roughness is clamped here (wider lobes are covered by the cosine component)."""
_SQRT2 = np.sqrt(2.0)


@dataclass(frozen=True)
class Component:
    kind: str           # "cosine", "ggx" or "beckmann" (half-vector distributions)
    alpha: float        # roughness of a half-vector component (nan for cosine)
    lobe: str           # the lobe prefix it stands for ("ct", "ct2", "diffraction"; "diffuse": every
    #                     diffuse lobe, for the cosine component)
    channel: int | None  # diffraction: the channel whose wavelength set alpha
    weight: float = 0.0


def _hv(h):
    """The attributes an NDF reference reads, from half-vectors (n, 3) with h_z > 0."""
    ch = h[:, 2]
    t2 = (h[:, 0] ** 2 + h[:, 1] ** 2) / np.maximum(ch * ch, 1e-300)
    return SimpleNamespace(ch=ch, t2=t2)


def half_vector(kind, alpha, u, v, xp=np):
    """The half-vector (x, y, z) distributed as D(h) cos(theta_h) for ``kind`` ggx or beckmann, from
    two uniform numbers in [0, 1), u < 1.  ``xp`` gives ``sqrt``, ``log1p``, ``cos`` and ``sin``:
    numpy here, Dr.Jit's in the Mitsuba BSDF, so that both draw by this one rule."""
    a2 = alpha * alpha
    if kind == "ggx":
        t2 = a2 * u / (1.0 - u)
    elif kind == "beckmann":
        t2 = -a2 * xp.log1p(-u)
    else:
        raise ValueError(kind)
    ch = 1.0 / xp.sqrt(1.0 + t2)
    sh = xp.sqrt(t2) * ch
    phi = 2.0 * np.pi * v
    return sh * xp.cos(phi), sh * xp.sin(phi), ch


def half_vector_density(D, ch, wo_dot_h):
    """The density per solid angle of wo when the half-vector is drawn as D(h) cos(theta_h) and wi
    reflected about it: D cos(theta_h) / (4 wo.h)."""
    return D * ch / (4.0 * wo_dot_h)


def cosine_density(co):
    """The density per solid angle of cosine-weighted hemisphere sampling: cos(theta_o) / pi."""
    return co * (1.0 / np.pi)


def _sample_h(kind, alpha, u, v):
    """Half-vectors (n, 3) distributed as D(h) cos(theta_h)."""
    return np.stack(half_vector(kind, alpha, np.clip(u, 0.0, 1.0 - 1e-12), v), axis=-1)


def _sample_cosine(u, v):
    r = np.sqrt(u)
    phi = 2.0 * np.pi * v
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - u, 0.0))], axis=-1)


def _ggx_alpha_at_half(t2_half):
    """The GGX alpha whose D(t2) / D(0) is 1/2 at tan^2 theta_h = t2_half."""
    return float(np.sqrt(t2_half / (_SQRT2 * (1.0 + t2_half) - 1.0)))


def _half_point(fn, lo, hi, iters=200):
    """x in [lo, hi] (log bisection) where fn(x) = 1/2, fn decreasing from ~1."""
    a, b = np.log(lo), np.log(hi)
    for _ in range(iters):
        m = 0.5 * (a + b)
        if fn(np.exp(m)) > 0.5:
            a = m
        else:
            b = m
    return float(np.exp(0.5 * (a + b)))


class Sampler:
    """A fitted model with its BRDF, pdf and sampling routine in the local frame."""

    def __init__(self, model: Model, values, n_albedo: int = 1024):
        self.model = model
        self.values = np.asarray(values, dtype=np.float64).copy()
        if self.values.shape != (model.n_params,):
            raise ValueError(f"expected {model.n_params} parameter values for {model.spec}, "
                             f"got shape {self.values.shape}")
        pos = {n: i for i, n in enumerate(model.names)}
        self._value = lambda name: self.values[..., pos[name]]
        comps = [Component("cosine", float("nan"), "diffuse", None)]
        for lb in model.lobes:
            if lb.role == "reflection":
                comps.append(self._ct_component(lb))
            elif lb.role == "diffraction":
                comps += self._diffraction_components(lb)
        self.components = self._weigh(comps, n_albedo)
        w = np.array([c.weight for c in self.components])
        self._cum = np.cumsum(w) / w.sum()

    # --- proposals ------------------------------------------------------------------------------
    def _lobe_consts(self, lb):
        return lb.consts(self._value)

    def _ct_component(self, lb):
        if lb.ndf.sampled_as:                  # the D is that distribution: sampled exactly from its alpha
            alpha = float(self._value(lb.slot_name("alpha")))
            return Component(lb.ndf.sampled_as, float(np.clip(alpha, *ALPHA_RANGE)), lb.prefix, None)
        consts = self._lobe_consts(lb)

        def ratio(t2):
            t2 = np.array([t2, 1e-300])
            c = SimpleNamespace(t2=t2, ch=1.0 / np.sqrt(1.0 + t2))
            with np.errstate(all="ignore"):
                D, _ = lb.ref_term(lb.ndf, c, self._value, consts)
            return D[0] / D[1]
        t2 = _half_point(ratio, 1e-14, 1e8)
        return Component("ggx", float(np.clip(_ggx_alpha_at_half(t2), *ALPHA_RANGE)), lb.prefix, None)

    def _diffraction_components(self, lb):
        consts = self._lobe_consts(lb)

        def S(f):
            v, _ = lb.ref_term(lb.psd, np.array([f]), self._value, consts)
            return float(v[0])
        f_half = _half_point(S, 1e-6, 1e6)
        out = []
        for ch, lam in enumerate(lb.lambdas):
            s = min(f_half * lam / 2.0, 0.999)       # sin(theta_h) at half maximum, cos(theta_d) ~ 1
            t2 = s * s / (1.0 - s * s)
            alpha = _ggx_alpha_at_half(t2)
            out.append(Component("ggx", float(np.clip(alpha, *ALPHA_RANGE)), lb.prefix, ch))
        return out

    def _weigh(self, comps, n):
        """Weights from each component's lobe albedo (mean over channels and 3 incidences)."""
        u = sobol_points(2, n, 1)
        albedo = []
        for c in comps:
            m = self.model.submodel(self.model.lobes_with_role("diffuse") if c.kind == "cosine" else
                                    [lb for lb in self.model.lobes if lb.prefix == c.lobe])
            if m is None:                          # defensive cosine component, no diffuse lobe
                albedo.append(0.0)
                continue
            vals = np.array([self._value(nm) for nm in m.names])
            est = []
            for th in np.radians([0.0, 30.0, 60.0]):
                wi = np.broadcast_to([np.sin(th), 0.0, np.cos(th)], (n, 3))
                wo, ok = self._draw(c, wi, u[:, 0], u[:, 1])
                p = self._pdf_component(c, wi, wo)
                ok &= p > 0
                f = np.zeros((3, n))
                if np.any(ok):
                    f[:, ok] = m.reference(Cells.from_directions(wi[ok], wo[ok]), vals, jacobian=False)
                    f[:, ok] *= wo[ok, 2] / p[ok]
                f = f.mean(axis=1)
                est.append(f[c.channel] if c.channel is not None else f.mean())
            albedo.append(max(float(np.mean(est)), 0.0))
        albedo = np.array(albedo)
        if not np.isfinite(albedo).all() or albedo.sum() <= 0:
            albedo = np.ones(len(comps))
        w = albedo / albedo.sum()
        w[0] = max(w[0], DEFENSIVE)               # comps[0] is the cosine component
        w /= w.sum()
        return [Component(c.kind, c.alpha, c.lobe, c.channel, float(x)) for c, x in zip(comps, w)]

    # --- per component ----------------------------------------------------------------------------
    @staticmethod
    def _draw(c, wi, u, v):
        """Directions from one component and whether each is valid (above the horizon)."""
        if c.kind == "cosine":
            wo = _sample_cosine(u, v)
            return wo, (wo[:, 2] > 0) & (wi[:, 2] > 0)
        h = _sample_h(c.kind, c.alpha, u, v)
        d = np.sum(wi * h, axis=-1)
        wo = 2.0 * d[:, None] * h - wi
        return wo, (d > 0) & (wo[:, 2] > 0) & (wi[:, 2] > 0)

    @staticmethod
    def _geometry(wi, wo):
        """What every component's pdf reads: (directions valid, cos theta_o, half-vector
        attributes, wo.h)."""
        up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        h = wi + wo
        nh = np.sqrt(np.sum(h * h, axis=-1))
        ok = up & (nh > 1e-12)
        h = np.where(ok[:, None], h / np.where(ok, nh, 1.0)[:, None], [0.0, 0.0, 1.0])
        d = np.sum(wo * h, axis=-1)
        return up, ok & (d > 0), _hv(h), d

    @staticmethod
    def _pdf_from(c, geo, wo):
        up, ok, hv, d = geo
        if c.kind == "cosine":
            return cosine_density(np.where(up, wo[:, 2], 0.0))
        D, _ = REGISTRY["ndf"][c.kind].reference(hv, alpha=c.alpha)
        return np.where(ok, half_vector_density(D, hv.ch, np.where(ok, d, 1.0)), 0.0)

    def _pdf_component(self, c, wi, wo):
        return self._pdf_from(c, self._geometry(wi, wo), wo)

    # --- the mixture ------------------------------------------------------------------------------
    def brdf(self, wi, wo):
        """f(wi, wo) in 1/sr, (3, n); 0 where either direction is below the horizon."""
        wi, wo = np.atleast_2d(wi), np.atleast_2d(wo)
        ok = (wi[:, 2] > 0) & (wo[:, 2] > 0) & (np.linalg.norm(wi + wo, axis=-1) > 1e-12)
        f = np.zeros((3, len(wi)))
        if np.any(ok):
            f[:, ok] = self.model.reference(Cells.from_directions(wi[ok], wo[ok]), self.values,
                                            jacobian=False)
        return np.where(np.isfinite(f), f, 0.0)

    def eval(self, wi, wo):
        """f(wi, wo) cos(theta_o), (3, n): what Mitsuba's BSDF.eval returns."""
        wo = np.atleast_2d(wo)
        return self.brdf(wi, wo) * np.maximum(wo[:, 2], 0.0)

    def pdf(self, wi, wo):
        """Density (per solid angle) with which `sample` draws wo given wi, (n,)."""
        wi, wo = np.atleast_2d(wi), np.atleast_2d(wo)
        geo = self._geometry(wi, wo)
        return sum(c.weight * self._pdf_from(c, geo, wo) for c in self.components)

    def eval_pdf(self, wi, wo):
        return self.eval(wi, wo), self.pdf(wi, wo)

    def sample(self, wi, u1, u2):
        """Draw wo for each wi: (wo (n, 3), pdf (n,), weight = eval / pdf (3, n), component (n,)).

        ``u1`` (n,) picks the component, ``u2`` (n, 2) the direction; invalid draws (below the
        horizon) have pdf 0 and weight 0."""
        wi = np.atleast_2d(np.asarray(wi, dtype=np.float64))
        n = len(wi)
        u1 = np.broadcast_to(np.asarray(u1, dtype=np.float64), (n,))
        u2 = np.broadcast_to(np.asarray(u2, dtype=np.float64), (n, 2))
        k = np.minimum(np.searchsorted(self._cum, u1, side="right"), len(self.components) - 1)
        wo = np.zeros((n, 3))
        valid = np.zeros(n, dtype=bool)
        for j, c in enumerate(self.components):
            sel = k == j
            if np.any(sel):
                wo[sel], valid[sel] = self._draw(c, wi[sel], u2[sel, 0], u2[sel, 1])
        wo[~valid] = [0.0, 0.0, 1.0]
        f, pdf = self.eval_pdf(wi, wo)
        pdf = np.where(valid, pdf, 0.0)
        weight = np.where(valid & (pdf > 0), f / np.where(pdf > 0, pdf, 1.0), 0.0)
        return wo, pdf, weight, k

    def describe(self):
        return "; ".join(f"{c.lobe}{'' if c.channel is None else '[' + 'rgb'[c.channel] + ']'}: "
                         f"{c.kind}{'' if c.kind == 'cosine' else f' alpha={c.alpha:.4g}'} "
                         f"w={c.weight:.3f}" for c in self.components)
