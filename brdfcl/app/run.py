"""A database fit as a user runs it: resume, batches, bad files, outputs as results arrive.

``fit_all`` is the Python API behind ``brdfcl fit-all``.  Materials are fitted in
batches (all materials of a batch share every launch); each finished material
is written at once (NAME.json, optionally NAME.binary with the fitted model),
and summary.csv is rewritten from every NAME.json in the output folder.

Input data is read-only: an output folder that is, holds or is inside the input folder, or
holds an input file (symlinks resolved), is refused before any work
(``check_output_not_input``).  Re-running into an output folder reuses a finished result only
if it was made with the same options (brdfcl.report.output.resume_state); a result of other options
stops the run before any work (``ResultsDiffer``) unless ``overwrite``.  A finished fit whose
export is missing is exported without refitting.

This is the top of the job-running layer: it imports the analysis (--select-lobes) and the
cluster runner (``client``), and they, like this module, take the input checks from
brdfcl.data.inputs and the writing of results from brdfcl.report.results, never from here.  The names
that moved there are still importable from here (``__all__``).
"""
from __future__ import annotations

import json
import time
from dataclasses import replace

from brdfcl.app.analyze import analyze
from brdfcl.app.cluster import fit_on_cluster
from brdfcl.data.inputs import FileReader, InputOverwriteError, check_output_dir, check_output_not_input, database_paths
from brdfcl.data.merl import material_name, read_merl
from brdfcl.optim.fit import FitOptions, load_batch
from brdfcl.report.output import export_fit, read_results, remove_stale_temporaries, resume_state
from brdfcl.report.results import Models, Progress, RunReport, finish_run, result_writer

# This module's API, with the names of brdfcl.data.inputs and brdfcl.report.results that callers import from here.
__all__ = ["FileReader", "InputOverwriteError", "Models", "OPTION_FLAGS", "Progress", "ResultsDiffer",
           "RunReport", "check_output_dir", "check_output_not_input", "database_paths", "finish_run",
           "fit_all", "result_writer", "write_pages"]


class ResultsDiffer(ValueError):
    """The output folder holds results made with other options than this run's."""


# CLI flags of recorded options, for messages (a dotted name first, then its first part)
OPTION_FLAGS = {"model": "--model", "metric": "--metric", "cosw": "--no-cos", "cutoff_deg": "--cutoff",
                "real": "--double", "global_method": "--global", "n_candidates": "--candidates",
                "n_starts": "--starts", "lm.max_iter": "--max-iter", "seed": "--seed", "fixed": "--fix",
                "ct_peak": "--ct-peak", "select_lobes": "--select-lobes", "free_peak": "--free-peak"}


def fit_all(source, out=None, options: FitOptions | None = None, batch=100, export=False,
            quiet=True, log=None, client=None, select_lobes=False, free_peak=False, overwrite=False,
            pages=False, **kw) -> RunReport:
    """Fit every material of a database; write results to ``out`` if given.

    ``source``: folder, file or list of files.  ``options`` or keyword arguments
    give the FitOptions.  ``client``: a dask.distributed Client to spread batches
    over workers (see brdfcl.app.cluster).  ``out`` may not be, hold or be inside the input
    (InputOverwriteError).  Results already in ``out`` are reused when made with the same
    options; results of other options raise ResultsDiffer before any work, or with
    ``overwrite`` are refitted and replaced.  ``pages``: write the run's report
    (``OUT/report/index.html``, brdfcl.report.view.pages) at the end (the CLI does unless --no-report)."""
    opts = options or FitOptions(**kw)
    log = log or (lambda s: None)
    t0 = time.perf_counter()
    paths = database_paths(source)
    report = RunReport()
    if select_lobes:        # what the lobe comparison fits with (brdfcl.analysis.analyze), so what is recorded
        opts = replace(opts, fixed={}, ct_peak=not free_peak)
    models = Models(opts, select_lobes=select_lobes, free_peak=free_peak)
    todo = paths
    if out is not None:
        check_output_not_input(source, out, paths)
        out = check_output_dir(out)
        todo = _resume(paths, out, models, export, overwrite, report, log)
    if select_lobes:
        _fit_selected(todo, out, opts, batch, export, report, log, t0, models)
    elif client is not None:
        fit_on_cluster(client, todo, out, opts, batch, export, report, log, quiet, t0)
    else:
        _fit_here(todo, out, models, batch, export, report, log, quiet, t0)
    if out is not None and pages:
        report.pages = write_pages(out, paths, log)
    return report


def write_pages(out, paths, log=None):
    """The run's report for the materials of ``paths`` that have a result in ``out``."""
    # local: brdfcl.report.view loads matplotlib, which a run without pages never needs
    from brdfcl.report.view.pages import Entry, write_report
    by_name = {material_name(p): p for p in paths}
    entries = [Entry.from_document(d, by_name[d["material"]]) for d in read_results(out)
               if d["material"] in by_name]
    index = write_report(out, entries, read_merl, title=f"brdfcl fits in {out}")
    if log:
        log(f"report: {index}")
    return index


def _fit_here(todo, out, models, batch, export, report, log, quiet, t0):
    """Fit in this process, a batch at a time, writing results as they finish."""
    progress = Progress(len(todo), quiet)
    try:
        for s in range(0, len(todo), batch):
            fitter = models.main_fitter()
            part = todo[s:s + batch]

            def on_error(item, e, part=part):
                path = getattr(item, "path", None) or str(item)
                report.skipped[path] = str(e)
                log(f"skipped: {e}")
            names, full, coarse = load_batch([FileReader(p) for p in part], fitter, on_error)
            if not names:
                continue
            log(f"batch of {len(names)} materials loaded")
            handle = result_writer(out, models, export, report, progress)
            fitter.fit(names, full, coarse, on_result=handle, log=log)
    finally:
        finish_run(progress, out, report, t0)


def _resume(paths, out, models, export, overwrite, report, log):
    """What is left to fit in ``out``: reuse finished results made with the same options (writing a
    missing export without refitting); stop on results of other options unless ``overwrite``."""
    remove_stale_temporaries(out)
    todo, differ, exports, replaced = [], [], [], 0
    for p in paths:
        name = material_name(p)
        state, info = resume_state(out, name, models.options)
        if state == "done":
            report.resumed.append(name)
            if export and not (out / f"{name}.binary").exists():
                exports.append(info)
        elif state == "differs" and not overwrite:
            differ.append((name, info))
        else:
            replaced += state == "differs"
            todo.append(p)
    if differ:
        raise ResultsDiffer(_differ_message(out, differ, len(paths), models.options))
    if report.resumed:
        log(f"resuming: {len(report.resumed)} materials already finished in {out}")
    if replaced:
        log(f"overwrite: refitting {replaced} results made with other options")
    for doc in exports:
        export_fit(out / f"{doc['material']}.binary", models.engine(doc["model"]),
                   {k: v["value"] for k, v in doc["params"].items()})
    if exports:
        log(f"exported {len(exports)} finished fits without refitting")
    return todo


def _differ_message(out, differ, total, current):
    name, (option, old, new) = differ[0]
    where = out / f"{name}.json"
    many = f" (and {len(differ) - 1} more of the {total} materials)" if len(differ) > 1 else ""
    if option is None:
        what = "was written by an older brdfcl that did not record its options"
    else:
        flag = OPTION_FLAGS.get(option) or OPTION_FLAGS.get(option.split(".")[0])
        if option == "ct_peak" and current.get("select_lobes"):     # --select-lobes sets it from --free-peak
            flag = "--free-peak"

        def show(v):
            plain = isinstance(v, (type(None), bool, int, float, str, list, dict))
            return json.dumps(v) if plain else "absent"
        what = (f"was made with other options: {option}{f' ({flag})' if flag else ''} is {show(old)} there, "
                f"{show(new)} now")
    return (f"{where} {what}{many}; to proceed, give a new --out, or --overwrite (overwrite=True) to "
            f"refit and replace those results")


def _fit_selected(paths, out, opts, batch, export, report, log, t0, models):
    """--select-lobes: the lobe comparison of brdfcl.analysis.analyze decides each material's model;
    its final fit (without the diffraction lobe where the verdict is 'none') is the result."""
    if not paths:
        report.seconds = time.perf_counter() - t0
        return report
    write = result_writer(out, models, export, report, Progress(0, True))
    def on_skip(path, why):
        report.skipped[path] = why
        log(f"skipped: {why}")
    analyze(paths, None, opts, batch=batch, log=log, figures=False, ct_peak=opts.ct_peak, on_skip=on_skip,
            on_material=lambda a: write(a.final, {"selected_by": "lobe comparison", "verdict": a.verdict}))
    report.seconds = time.perf_counter() - t0
    return report
