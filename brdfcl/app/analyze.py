"""The analysis job: every material of a database through brdfcl.analysis, in batches.

The job runner (brdfcl.app.runner) lists and checks the input and output, skips unreadable
files with their reason and hands each analysed material to the writers of an analysis
(brdfcl.report.writers: NAME.exr, the figures, analysis.csv and index.html, the report pages).
This module fits the compared models once per batch and analyses each material
(brdfcl.analysis.analyze.analyze_material).
"""
from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from brdfcl._words import count
from brdfcl.analysis.analyze import COMPARED, MaterialAnalysis, analyze_material, lobe_images
from brdfcl.analysis.gradient import phi90_slice
from brdfcl.analysis.law import GREY, grey_fitters
from brdfcl.analysis.samples import SampleAnalysis, analyze_samples
from brdfcl.app.runner import Runner
from brdfcl.data.errors import DataError
from brdfcl.data.geometry import table_values
from brdfcl.data.measurement import Measurement
from brdfcl.data.merl import N_CELLS, MerlError
from brdfcl.model.compose import Model
from brdfcl.optim.fit import FitOptions, Fitter, same_cells
from brdfcl.optim.selection import variants
from brdfcl.report.writers import ANALYSIS, Item


class Analyses(list):
    """What ``analyze`` returns: the list of MaterialAnalysis, plus ``skipped``, {path: reason} for
    every file that could not be read (as RunReport.skipped of ``fit_all``); ``ok`` if none was."""

    def __init__(self, items=(), skipped=None):
        super().__init__(items)
        self.skipped = dict(skipped or {})

    @property
    def ok(self) -> bool:
        return not self.skipped


def analyze(source: Any, out: str | os.PathLike | None = None, options: FitOptions | None = None,
            batch: int = 100, log: Callable[[str], None] | None = None, figures: bool = True,
            on_material: Callable[[MaterialAnalysis], None] | None = None, ct_peak: bool = True,
            on_skip: Callable[[str, str], None] | None = None, pages: bool = False, rgb: bool = False) -> Analyses:
    """Analyse every material of a database; writes analysis.csv, maps, figures and index.html,
    and with ``pages`` the run's report (``OUT/report/index.html``, brdfcl.report.view.pages).

    A file that cannot be read is skipped: recorded in the result's ``skipped`` and reported to
    ``on_skip(path, reason)`` (default: ``log("skipped: reason")``); the rest is analysed.  Raises
    MerlError when files were given but none could be read; before any work, OSError when ``out``
    cannot be written and brdfcl.data.inputs.InputOverwriteError (also brdfcl.app.run's) when it is, holds or
    is inside the input.  ``rgb``: spectral measurements as linear sRGB (brdfcl.data.rgb.to_rgb).

    A table (a dense layout) gets the gradient test and the wavelength check on its grid; scattered
    samples the wavelength law by model comparison (brdfcl.analysis.samples)."""
    opts = options or FitOptions()
    specs = variants(Model(opts.model).spec)
    if set(specs) != {"full", "no_diffraction", "no_ct"}:
        raise ValueError(f"analysis needs a model with diffuse, diffraction and Cook-Torrance lobes, "
                         f"got '{opts.model}'")
    run = Runner(source, out, ANALYSIS, log=log, on_skip=on_skip, figures=figures, pages=pages)
    results = Analyses()
    results.skipped = run.report.skipped
    fitters = variant_fitters(opts, specs, ct_peak)
    if ct_peak:
        specs["full_free"] = specs["full_local"] = specs["full"]

    groups = run.read(run.paths, rgb)
    tables = [m for g in groups for m in g if m.layout.dense]

    def finished(a, path):
        run.done(Item(a.name, path, analysis=a))
        results.append(a)
        if on_material:
            on_material(a)

    for part in run.batches(tables, batch):
        fits = {}
        base = fitters["full"]
        loaded = base.load(part, on_error=lambda m, e: run.skip(m.path or m.name, e))
        read = [part[k] for k in loaded.read]
        for k, f in fitters.items():
            t = time.perf_counter()
            fitted = f.fit_loaded(loaded) if same_cells(base, f) else f.fit(read)
            fits[k] = {r.name: r for r in fitted}
            run.log(f"fitted {count(len(read), 'material')} with {specs.get(k, specs['full'])} ({k}) in "
                    f"{time.perf_counter() - t:.1f} s")
        del loaded
        best_of_both(fits, "full", "full_local")
        best_of_both(fits, GREY, GREY + "_local")
        for m in read:
            try:
                brdf = table_values(m, np.arange(N_CELLS))      # the gradient test's grid
            except (DataError, MerlError) as e:          # changed or removed since it was fitted
                run.skip(m.path, e)
                continue
            name = m.name
            a = analyze_material(name, brdf, {k: fits[k][name] for k in fits}, specs)
            if figures or out is not None:
                a.slices = {"measured": phi90_slice(brdf)[0], **lobe_images(specs["full"], a.fits["full"].params)}
            finished(a, m.path)
            run.log(f"{name}: {a.verdict} (lobes {a.specs[a.selected]}, gradient score "
                    f"{a.gradient.mean_score:.2f}, wavelength law ratio {a.law_ratio:.3f})")
    scattered = [g for g in groups if not g[0].layout.dense]
    for path, sa in _analyze_samples(run, scattered, opts, specs, ct_peak, batch):
        finished(sa, path)
        n = sa.spectral.exponent if sa.spectral else float("nan")
        run.log(f"{sa.name}: {sa.verdict} (lobes {sa.specs[sa.selected]}, wavelength law ratio {sa.law_ratio:.3f} "
                f"over {count(len(sa.lambdas), 'band')}, lambda exponent {n:.2f}; gradient test not run on scattered "
                "samples)")
    run.finish()
    if results.skipped and not results:
        where = source if isinstance(source, (str, os.PathLike)) else "the given files"
        n = len(results.skipped)
        raise MerlError(f"{where}: no readable material to analyse ({n} file{'s' * (n != 1)} skipped)")
    return results


def variant_fitters(opts: FitOptions, specs: dict, ct_peak: bool, lambdas: tuple | None = None) -> dict:
    """A Fitter per compared variant (brdfcl.optim.selection.variants) and, with the peak
    constraint, the full model from a global search without it (``full_local``) and the full model
    without the constraint (``full_free``), sharing the full model's engine; and the wavelength
    law's rivals, the full model with every channel at one wavelength (brdfcl.analysis.law)."""
    fitters = {k: Fitter(replace(opts, model=sp, fixed={}, ct_peak=ct_peak), lambdas=lambdas)
               for k, sp in specs.items() if k in COMPARED}
    base = fitters["full"]
    if ct_peak:     # the constrained fit from both global searches (brdfcl.optim.fit), and a free one
        for key, o in (("full_local", replace(base.opts, ct_peak_global=False)),
                       ("full_free", replace(base.opts, ct_peak=False))):
            fitters[key] = Fitter(o, engine=base.engine, lambdas=lambdas)
    fitters.update(grey_fitters(base, lambdas or Model(specs["full"]).lambdas, ct_peak))
    return fitters


def best_of_both(fits: dict, key: str, other: str) -> None:
    """Keep under ``key`` each material's better fit of ``key`` and ``other`` (removed)."""
    if other in fits:
        alt = fits.pop(other)
        fits[key] = {n: (r if r.loss <= alt[n].loss else alt[n]) for n, r in fits[key].items()}


def _analyze_samples(run: Runner, groups: list[list[Measurement]], opts: FitOptions, specs: dict, ct_peak: bool,
                     batch: int) -> Iterator[tuple[str, SampleAnalysis]]:
    """(path, SampleAnalysis) of each scattered measurement, fitted with every compared model in
    groups of equal bands (brdfcl.analysis.samples)."""
    for group in groups:
        lambdas = tuple(float(x) for x in group[0].wavelengths)
        fitters = variant_fitters(opts, specs, ct_peak, lambdas)
        for part in run.batches(group, batch):
            samples = list(part)
            fits = {}
            for k, f in fitters.items():
                t = time.perf_counter()
                fits[k] = {r.name: r for r in f.fit(samples)}
                run.log(f"fitted {count(len(samples), 'sample set')} ({count(len(lambdas), 'band')}) with "
                        f"{specs.get(k, specs['full'])} ({k}) in {time.perf_counter() - t:.1f} s")
            best_of_both(fits, "full", "full_local")
            best_of_both(fits, GREY, GREY + "_local")
            for s in part:
                path = s.path or s.name
                if not any(fits[k][s.name].success for k in COMPARED if k in fits):
                    run.skip(path, f"{path}: no compared model could be fitted")
                    continue
                yield path, analyze_samples(s, {k: fits[k][s.name] for k in fits}, specs, cutoff_deg=opts.cutoff_deg)
