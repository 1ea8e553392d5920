"""A database fit as a user runs it: ``fit_all``, the Python API behind ``brdfcl fit-all``.

Materials are fitted in batches (all materials of a batch share every launch) by the one job
runner (brdfcl.app.runner): each finished material goes at once to the writers of a fit job
(brdfcl.report.writers: NAME.json, the exports asked for such as NAME.binary, summary.csv
rewritten from every NAME.json in the output folder; the run's report pages at the end).

Input data is read-only: an output folder that is, holds or is inside the input folder, or
holds an input file (symlinks resolved), is refused before any work
(brdfcl.data.inputs.check_output_not_input).  Re-running into an output folder reuses a finished
result only if it was made with the same options (brdfcl.app.resume); a result of other options
stops the run before any work (``ResultsDiffer``) unless ``overwrite``.  A finished fit whose
export is missing is exported without refitting.

This module only chooses how a batch is fitted: here, on a Dask cluster (``client``,
brdfcl.app.cluster) or through the lobe comparison (``select_lobes``, brdfcl.app.analyze); they
import the runner, never this module.  The names callers import from here are in ``__all__``.
"""
from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

from brdfcl.app.analyze import analyze
from brdfcl.app.cluster import fit_on_cluster
from brdfcl.app.resume import OPTION_FLAGS, ResultsDiffer, resume
from brdfcl.app.runner import Models, Progress, Runner, RunReport
from brdfcl.data.inputs import InputOverwriteError, check_output_dir, check_output_not_input, database_paths
from brdfcl.data.merl import material_name
from brdfcl.model.compose import Model
from brdfcl.optim.fit import FitOptions
from brdfcl.optim.forms import FormFitter, form_keys, resolve
from brdfcl.report.published import read_published
from brdfcl.report.writers import FIT, IMPLEMENTED_WRITERS, Job, export_writers

# This module's API, with the names of the runner and of brdfcl.data.inputs callers import from here.
__all__ = ["InputOverwriteError", "Models", "OPTION_FLAGS", "Progress", "ResultsDiffer",
           "RunReport", "check_output_dir", "check_output_not_input", "database_paths", "fit_all",
           "write_pages"]


def fit_all(source, out=None, options: FitOptions | None = None, batch=100, export: bool | str | Iterable[str] = False,
            quiet=True, log=None, client=None, select_lobes=False, free_peak=False, overwrite=False,
            pages=False, rgb=False, forms: str | None = "default", published=None, **kw) -> RunReport:
    """Fit every material of a database; write results to ``out`` if given.

    ``source``: folder, file or list of files.  ``options`` or keyword arguments
    give the FitOptions.  ``export``: True writes each fit as a MERL table (NAME.binary); or
    the names of the exports to write (brdfcl.report.writers.export_writers: "merl",
    "brdf_explorer").  ``client``: a dask.distributed Client to spread batches
    over workers (see brdfcl.app.cluster).  ``out`` may not be, hold or be inside the input
    (InputOverwriteError).  Results already in ``out`` are reused when made with the same
    options; results of other options raise ResultsDiffer before any work, or with
    ``overwrite`` are refitted and replaced.  ``pages``: write the run's report
    (``OUT/report/index.html``, brdfcl.report.view.pages) at the end (the CLI does unless --no-report).
    ``published``: a CSV of each material's best published fit and its rmse_log
    (brdfcl.report.published), read before any work; the report names that fit and the ratio.

    Every file a reader of brdfcl.data.readers reads is a measurement; those of the same channels
    (and, for tables, the same layout) share a batch (brdfcl.app.runner.Runner.read).  Spectral
    measurements are fitted with one channel per band at its wavelength; ``rgb`` first converts
    their spectra to linear sRGB (brdfcl.data.rgb.to_rgb: D65, CIE 1931 2 deg), fitted with the
    R, G, B wavelengths of MERL tables.  Their spectral fits have no MERL / BRDF Explorer export (an
    RGB fit has); their report page shows the samples against the fit in the plane of incidence.

    ``forms``: the candidate forms of the reflection lobe (brdfcl.optim.forms): each material is
    fitted in each and the form of least penalised error kept, recorded in NAME.json (``form``,
    ``form_errors``); with ``select_lobes`` its lobes are then compared in that form.  A list of
    NDF:FRESNEL pairs (``gtr:dielectric,abc:schlick``, with NDF:SHADOWING:FRESNEL triples such as
    ``beckmann:vcavity:schlick``) or ``NDF[,NDF...][:FRESNEL[,FRESNEL...]]``;
    ``"default"``: brdfcl.optim.forms.DEFAULT_FORMS for the default model with nothing fixed (a
    ``model`` keyword is a model asked for: it is fitted as given); None or ``"none"``: the model as
    given."""
    opts = options or FitOptions(**kw)
    scores = read_published(published) if published is not None else {}
    forms = resolve(forms, opts, model_given="model" in kw)
    form_specs = form_keys(opts.model, forms) if forms is not None else None
    for spec in (form_specs or {}).values():     # a fixed parameter every form must have: before any work
        Model(spec, fixed=opts.fixed)
    if select_lobes:        # what the lobe comparison fits with (brdfcl.analysis.analyze), so what is recorded
        opts = replace(opts, fixed={}, ct_peak=not free_peak)
    models = Models(opts, select_lobes=select_lobes, free_peak=free_peak, forms=form_specs)
    recorded = {**models.options, "export": bool(export), **({"rgb": True} if rgb else {})}
    run = Runner(source, out, FIT, log=log, quiet=quiet, options=recorded,
                 exports=_exports(export), pages=pages, model=models.model, engine=models.engine,
                 published=scores)
    todo = resume(run, recorded, overwrite) if run.job is not None else run.paths
    if select_lobes:
        _fit_selected(run, todo, opts, batch, form_specs, rgb)
    elif client is not None:
        fit_on_cluster(client, run, todo, opts, batch, form_specs, rgb)
    else:
        _fit_here(run, todo, models, batch, rgb)
    return run.finish()


def write_pages(out: str | os.PathLike, paths: Iterable[Any], log=None) -> Path | None:
    """The run's report for the materials of ``paths`` that have a result in ``out``."""
    job = Job(FIT, Path(out), pages=True, tables={material_name(p): os.fspath(p) for p in paths})
    if log:
        job.log = log
    return IMPLEMENTED_WRITERS["pages"].finish(job, [])


def _exports(export: bool | str | Iterable[str]) -> frozenset[str]:
    """The export writers ``export`` asks for: True is the MERL table (--export-merl)."""
    if isinstance(export, bool):
        return frozenset({"merl"} if export else ())
    names = frozenset([export] if isinstance(export, str) else export)
    valid = export_writers()
    bad = sorted(names - set(valid))
    if bad:
        raise ValueError(f"unknown export {', '.join(bad)}; valid: {', '.join(valid)}")
    return names


def _fit_here(run: Runner, todo: list[str], models: Models, batch: int, rgb: bool = False) -> None:
    """Fit in this process, a batch at a time, each result written as it finishes (with forms: as
    its form is chosen); measurements of other channels or layouts in batches of their own."""
    groups = run.read(todo, rgb)
    with run.tracking(sum(len(g) for g in groups)):
        for group in groups:
            fitter = models.fitter(tuple(group[0].wavelengths))
            for part in run.batches(group, batch):
                run.fit_batch(fitter, part)


def _fit_selected(run: Runner, todo: list[str], opts: FitOptions, batch: int, forms: dict | None = None,
                  rgb: bool = False) -> None:
    """--select-lobes: the lobe comparison of brdfcl.analysis.analyze decides each material's model;
    its final fit (without the diffraction lobe where the verdict is 'none') is the result.  With
    ``forms`` ({key: model spec}, brdfcl.optim.forms.form_variants) each material's form is chosen
    first, and its lobes are compared in that form."""
    if not todo:
        return
    with run.tracking(len(todo)):
        chosen: dict = {opts.model: (todo, {})}
        if forms:
            chosen = _choose_forms(run, todo, opts, batch, forms, rgb)
        for spec, (paths, info) in chosen.items():
            def done(a: Any, info: dict = info) -> None:
                run.fitted(a.final, {"selected_by": "lobe comparison", "verdict": a.verdict, **info.get(a.name, {})})
            analyze(paths, None, replace(opts, model=spec), batch=batch, log=run.log, figures=False,
                    ct_peak=opts.ct_peak, on_skip=run.skip, on_material=done, rgb=rgb)


def _choose_forms(run: Runner, todo: list[str], opts: FitOptions, batch: int, forms: dict, rgb: bool) -> dict:
    """{model spec: (paths, {material: what NAME.json records of the choice})}: every material fitted
    in every form (brdfcl.optim.forms.FormFitter, one read of each batch), the least penalised kept;
    no lobe left out there: the lobe comparison decides the lobes."""
    chosen: dict[str, tuple[list, dict]] = {}
    for group in run.read(todo, rgb):
        lambdas = tuple(group[0].wavelengths)
        fitter = FormFitter(opts, forms, lambdas=None if lambdas == Model(opts.model).lambdas else lambdas,
                            drop_traded=False)
        for part in run.batches(group, batch):
            path_of = {m.name: m.path or m.name for m in part}
            for res, record in run.fit_batch(fitter, part, on_result=lambda r, rec: None):
                path = path_of[res.name]
                if record is None or record["form"] is None:
                    run.skip(path, f"{path}: no form could be fitted")
                    continue
                paths_, info = chosen.setdefault(forms[record["form"]], ([], {}))
                paths_.append(path)
                info[res.name] = record
                run.log(f"{res.name}: form {record['form']}")
    return chosen
