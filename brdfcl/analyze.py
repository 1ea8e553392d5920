"""Which physical effect makes which part of each measured BRDF (docs/spec.md section 5).

For every material: the gradient test (brdfcl.gradient_test), the wavelength check
(brdfcl.wavelength), and the lobe comparison (brdfcl.selection: fits with and without
the diffraction and Cook-Torrance lobes, sharing one load of the data).  Each test is
necessary, none sufficient (a broad Cook-Torrance lobe can tilt the level lines like
f does, and a misfitting CT lobe can be patched by a diffraction lobe), so the verdict
is ``diffraction`` only when the lobe comparison keeps the diffraction lobe and neither
the gradient test (score >= 0.5) nor the wavelength check (ratio >= 1.5, see
brdfcl.wavelength) contradicts it where it can decide; ``none`` otherwise.  A material
with verdict ``none`` gets its final fit without the diffraction lobe.

The fits give the specular peak to Cook-Torrance (brdfcl.peak_order, the talk's model);
the full model is also fitted without that constraint (``full_free``) so that the table
shows what the constraint costs and which lobe a free fit would put on the peak.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import report
from .fit import FitOptions, Fitter, load_batch
from .geometry import bin_centres, directions
from .gradient_test import GradientMap, gradient_test, phi90_slice
from .inputs import FileReader, check_output_not_input, database_paths
from .lobes.cells import Cells
from .merl import MerlError, read_merl
from .model import Model
from .peak_order import peak_cell
from .selection import select, variants
from .wavelength import WavelengthCheck, wavelength_check

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
    """Share of the fitted value at the specular peak (brdfcl.peak_order.peak_cell) due to diffraction."""
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


class Analyses(list):
    """What ``analyze`` returns: the list of MaterialAnalysis, plus ``skipped``, {path: reason} for
    every file that could not be read (as RunReport.skipped of ``fit_all``); ``ok`` if none was."""

    def __init__(self, items=(), skipped=None):
        super().__init__(items)
        self.skipped = dict(skipped or {})

    @property
    def ok(self):
        return not self.skipped


def analyze(source, out=None, options: FitOptions | None = None, batch=100, log=None, figures=True,
            on_material=None, ct_peak=True, on_skip=None, pages=False) -> Analyses:
    """Analyse every material of a database; writes analysis.csv, maps, figures and index.html,
    and with ``pages`` the run's report (``OUT/report/index.html``, brdfcl.view.pages).

    A file that cannot be read is skipped: recorded in the result's ``skipped`` and reported to
    ``on_skip(path, reason)`` (default: ``log("skipped: reason")``); the rest is analysed.  Raises
    MerlError when files were given but none could be read; before any work, OSError when ``out``
    cannot be written and brdfcl.inputs.InputOverwriteError (also brdfcl.run's) when it is, holds or
    is inside the input."""
    opts = options or FitOptions()
    log = log or (lambda s: None)
    on_skip = on_skip or (lambda path, why: log(f"skipped: {why}"))
    specs = variants(Model(opts.model).spec)
    if set(specs) != {"full", "no_diffraction", "no_ct"}:
        raise ValueError(f"analysis needs a model with diffuse, diffraction and Cook-Torrance lobes, "
                         f"got '{opts.model}'")
    paths = database_paths(source)
    results = Analyses()
    if out is not None:                     # one-line errors, before any work
        check_output_not_input(source, out, paths)
        report.prepare(out)
    fitters = {k: Fitter(replace(opts, model=s, fixed={}, ct_peak=ct_peak)) for k, s in specs.items()}
    base = fitters["full"]
    if ct_peak:     # the constrained fit from both global searches (brdfcl.fit), and a free one
        fitters["full_local"] = Fitter(replace(base.opts, ct_peak_global=False), engine=base.engine)
        fitters["full_free"] = Fitter(replace(base.opts, ct_peak=False), engine=base.engine)
        specs["full_free"] = specs["full_local"] = specs["full"]

    path_of = {}

    def skip(item, e):
        path = getattr(item, "path", None) or str(item)
        results.skipped[path] = str(e)
        on_skip(path, str(e))
    for s in range(0, len(paths), batch):
        part = paths[s:s + batch]
        names, full, coarse = load_batch([FileReader(p) for p in part], base, on_error=skip)
        if not names:
            continue
        read = [p for p in part if p not in results.skipped]      # in the order of names
        fits = {}
        for k, f in fitters.items():
            t = time.perf_counter()
            fits[k] = {r.name: r for r in f.fit(names, full, coarse)}
            log(f"fitted {len(names)} materials with {specs[k]} ({k}) in {time.perf_counter() - t:.1f} s")
        del full, coarse
        if "full_local" in fits:
            other = fits.pop("full_local")
            fits["full"] = {n: (r if r.loss <= other[n].loss else other[n]) for n, r in fits["full"].items()}
        for name, path in zip(names, read):
            try:
                brdf = read_merl(path).brdf()
            except MerlError as e:          # changed or removed since it was fitted
                skip(FileReader(path), e)
                continue
            a = analyze_material(name, brdf, {k: fits[k][name] for k in fits}, specs)
            if figures or out is not None:
                a.slices = {"measured": phi90_slice(brdf)[0], **lobe_images(specs["full"], a.fits["full"].params)}
            if out is not None:
                report.write_material(out, a, figures=figures)
            results.append(a)
            path_of[name] = path
            if on_material:
                on_material(a)
            log(f"{name}: {a.verdict} (lobes {a.specs[a.selected]}, gradient score "
                f"{a.gradient.mean_score:.2f}, wavelength ratio {a.wavelength.ratio:.2f})")
        if out is not None:
            report.write_index(out, results)
    if out is not None and pages and results:
        write_pages(out, results, path_of, figures, log)
    if results.skipped and not results:
        where = source if isinstance(source, (str, os.PathLike)) else "the given files"
        n = len(results.skipped)
        raise MerlError(f"{where}: no readable material to analyse ({n} file{'s' * (n != 1)} skipped)")
    return results


def write_pages(out, analyses, path_of, figures=True, log=None):
    """The run's report: each material's final fit with its verdict and analysis figures."""
    # local: brdfcl.view loads matplotlib, which an analysis without pages never needs
    from .view.pages import Entry, write_report
    fig = Path(out) / "figures"
    entries = [Entry.from_result(a.final, path_of[a.name], verdict=a.verdict,
                                 figures=[fig / f"{a.name}_{k}.png" for k in ("gradient", "wavelength", "components")]
                                 if figures else []) for a in analyses]
    index = write_report(out, entries, read_merl, title=f"brdfcl analysis of {len(entries)} materials")
    if log:
        log(f"report: {index}")
    return index
