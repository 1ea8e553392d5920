"""The analysis job: every material of a database through brdfcl.analysis, in batches.

Reads the files (skipping unreadable ones with their reason), fits the compared models once per
batch, analyses each material (brdfcl.analysis.analyze.analyze_material) and writes analysis.csv,
the figures and the index (brdfcl.report.figures) and, on request, the run's report pages.
"""
from __future__ import annotations

import os
import time
from dataclasses import replace
from pathlib import Path

from brdfcl.analysis.analyze import analyze_material, lobe_images
from brdfcl.analysis.gradient import phi90_slice
from brdfcl.data.inputs import FileReader, check_output_not_input, database_paths
from brdfcl.data.merl import MerlError, read_merl
from brdfcl.model.compose import Model
from brdfcl.optim.fit import FitOptions, Fitter, load_batch
from brdfcl.optim.selection import variants
from brdfcl.report import figures as report


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
    and with ``pages`` the run's report (``OUT/report/index.html``, brdfcl.report.view.pages).

    A file that cannot be read is skipped: recorded in the result's ``skipped`` and reported to
    ``on_skip(path, reason)`` (default: ``log("skipped: reason")``); the rest is analysed.  Raises
    MerlError when files were given but none could be read; before any work, OSError when ``out``
    cannot be written and brdfcl.data.inputs.InputOverwriteError (also brdfcl.app.run's) when it is, holds or
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
    if ct_peak:     # the constrained fit from both global searches (brdfcl.optim.fit), and a free one
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
    # local: brdfcl.report.view loads matplotlib, which an analysis without pages never needs
    from brdfcl.report.view.pages import Entry, write_report
    fig = Path(out) / "figures"
    entries = [Entry.from_result(a.final, path_of[a.name], verdict=a.verdict,
                                 figures=[fig / f"{a.name}_{k}.png" for k in ("gradient", "wavelength", "components")]
                                 if figures else []) for a in analyses]
    index = write_report(out, entries, read_merl, title=f"brdfcl analysis of {len(entries)} materials")
    if log:
        log(f"report: {index}")
    return index
