"""Which physical effect makes which part of each measured BRDF (docs/spec.md section 5).

For every material: the gradient test (brdfcl.analysis.gradient), the wavelength check
(brdfcl.analysis.wavelength), and the lobe comparison (brdfcl.optim.selection: fits with and without
the diffraction and Cook-Torrance lobes, sharing one load of the data).  Each test is
necessary, none sufficient (a broad Cook-Torrance lobe can tilt the level lines like
f does, and a misfitting CT lobe can be patched by a diffraction lobe), so the verdict
is ``diffraction`` only when the lobe comparison keeps the diffraction lobe and neither
the gradient test (score >= 0.5) nor the wavelength check (ratio >= 1.5, see
brdfcl.analysis.wavelength) contradicts it where it can decide; ``none`` otherwise.  A material
with verdict ``none`` gets its final fit without the diffraction lobe.

The fits give the specular peak to Cook-Torrance (brdfcl.optim.peak_order, the talk's model);
the full model is also fitted without that constraint (``full_free``) so that the table
shows what the constraint costs and which lobe a free fit would put on the peak.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from brdfcl.analysis.gradient import GradientMap, gradient_test
from brdfcl.analysis.wavelength import WavelengthCheck, wavelength_check
from brdfcl.data.geometry import bin_centres, directions
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.optim.peak_order import peak_cell
from brdfcl.optim.selection import select

MIN_DECIDABLE = 30            # gradient test cells below which it is inconclusive
COMPARED = ("full", "no_diffraction", "no_ct")


@dataclass
class MaterialAnalysis:
    name: str
    verdict: str                          # "diffraction" or "none"
    selected: str                         # variant key chosen by the lobe comparison
    final_model: str
    fits: dict                            # variant key -> FitResult
    specs: dict                           # variant key -> model spec
    penalised: dict
    gradient: GradientMap
    wavelength: WavelengthCheck
    peak_share_diffraction: float         # share of the fitted peak value from the diffraction lobe
    peak_share_free: float                # the same for the fit without the peak constraint
    slices: dict = field(default_factory=dict)   # name -> (3, 90, 90) phi_d ~ 90 deg images

    @property
    def final(self):
        return next(r for k, r in self.fits.items() if self.specs[k] == self.final_model and k in COMPARED)

    def row(self):
        g, w = self.gradient, self.wavelength
        band = g.th_range_deg[1]
        out = {"material": self.name, "verdict": self.verdict, "selected_lobes": self.specs[self.selected],
               "final_model": self.final_model}
        for c, ch in enumerate("rgb"):
            out[f"grad_score_{ch}"] = _fmt(g.score[c])
        out["grad_cells"] = int(g.n_cells.sum())
        out["grad_band_deg_g"] = f"{band[0]:.1f}-{band[1]:.1f}" if band else ""
        out["wavelength_spread"] = _fmt(w.spread)
        out["wavelength_spread_f0"] = _fmt(w.spread_f0)
        out["wavelength_ratio"] = _fmt(w.ratio)
        for k in ("full", "no_diffraction", "no_ct"):
            r = self.fits.get(k)
            out[f"rmse_log_{k}"] = _fmt(r.errors["rmse_log"]) if r else ""
            out[f"penalised_{k}"] = _fmt(self.penalised.get(k, np.nan)) if r else ""
        free = self.fits.get("full_free")
        out["rmse_log_full_free"] = _fmt(free.errors["rmse_log"]) if free else ""
        out["peak_share_diffraction"] = _fmt(self.peak_share_diffraction)
        out["peak_share_free"] = _fmt(self.peak_share_free)
        return out


def _fmt(x):
    return "" if x is None or not np.isfinite(x) else f"{x:.5g}"


def slice_cells(phi_bins=slice(80, 100)):
    """Cells of the phi_d ~ 90 deg slice (90 * 90 * 20), for model images matching the data slice."""
    th, td, pd = bin_centres()
    TH, TD, PD = np.meshgrid(th, td, pd[phi_bins], indexing="ij")
    wi, wo = directions(TH.ravel(), TD.ravel(), PD.ravel())
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    return Cells.from_directions(wi[ok], wo[ok]), ok, TH.shape


def lobe_images(spec, params):
    """(3, 90, 90) images of each lobe group at phi_d ~ 90: diffuse+diffraction, CT, full."""
    cells, ok, shape = slice_cells()
    out = {}
    model = Model(spec)
    groups = {"diffuse_diffraction": model.prefixes_with_role("diffuse", "diffraction"),
              "ct": model.prefixes_with_role("reflection"), "full": None}
    for key, keep in groups.items():
        p = np.full((3, ok.size), np.nan)
        p[:, ok] = model.reference(cells, model.only_lobes(params, keep), jacobian=False)
        with np.errstate(invalid="ignore", divide="ignore"):
            n = np.isfinite(p.reshape(3, *shape)).sum(-1)
            img = np.nansum(p.reshape(3, *shape), axis=-1) / np.maximum(n, 1)
        out[key] = np.where(n > 0, img, np.nan)
    return out


def peak_share(spec, params):
    """Share of the fitted value at the specular peak (brdfcl.optim.peak_order.peak_cell) due to diffraction."""
    model = Model(spec)
    if not model.has_role("diffraction"):
        return 0.0
    cells = peak_cell()
    total = model.reference(cells, model.only_lobes(params, None), jacobian=False).sum()
    part = model.reference(cells, model.only_lobes(params, model.prefixes_with_role("diffraction")),
                           jacobian=False).sum()
    return float(part / max(total, 1e-300))


def analyze_material(name, brdf, fits, specs) -> MaterialAnalysis:
    errors = {k: r.errors["rmse_log"] for k, r in fits.items() if r.success and k in COMPARED}
    sel, pen = select(errors, {k: specs[k] for k in errors})
    gm = gradient_test(brdf)
    full = fits["full"]
    full_model = Model(specs["full"])
    diffuse = [sum(full.params.get(lb.slot_name("rho", ch), 0.0) for lb in full_model.lobes_with_role("diffuse"))
               / np.pi for ch in range(3)]
    wl = wavelength_check(brdf, diffuse, full_model.lambdas)
    lobe_says = Model(specs[sel]).has_role("diffraction")
    decidable = gm.n_cells.sum() >= MIN_DECIDABLE
    grad_says = (gm.mean_score >= 0.5) if decidable else None
    wl_says = wl.consistent
    verdict = "diffraction" if lobe_says and grad_says is not False and wl_says is not False else "none"
    if verdict == "none" and lobe_says:
        final_key = "no_diffraction" if "no_diffraction" in fits else sel
    else:
        final_key = sel
    free = fits.get("full_free")
    return MaterialAnalysis(name, verdict, sel, specs[final_key], fits, specs, pen, gm, wl,
                            peak_share(specs["full"], full.params),
                            peak_share(specs["full"], free.params) if free else float("nan"))


