"""A database fit as a user runs it: resume, batches, bad files, outputs as results arrive.

``fit_all`` is the Python API behind ``brdfcl fit-all``.  Materials are fitted in
batches (all materials of a batch share every launch); each finished material
is written at once (NAME.json, optionally NAME.binary with the fitted model),
and summary.csv is rewritten from every NAME.json in the output folder.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path


from .engine import Engine
from .fit import FitOptions, Fitter, load_batch
from .merl import MerlError, list_database, material_name, read_merl
from .model import Model
from .output import (export_fit, is_finished, remove_stale_temporaries, result_document, write_result,
                     write_summary)


@dataclass
class RunReport:
    results: list = field(default_factory=list)       # FitResult of the materials fitted now
    resumed: list = field(default_factory=list)       # names already finished in the output folder
    skipped: dict = field(default_factory=dict)       # path -> reason
    seconds: float = 0.0

    @property
    def ok(self):
        return not self.skipped and all(r.success for r in self.results)


def database_paths(source) -> list[str]:
    """A folder (its .binary files), a single file, or a list of files."""
    if isinstance(source, (str, os.PathLike)):
        return [os.fspath(source)] if os.path.isfile(source) else list_database(source)
    return [os.fspath(p) for p in source]


def check_output_dir(out):
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".write-test-{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError as e:
        raise OSError(f"{out}: output folder cannot be written: {e.strerror or e}") from None
    return out


class Progress:
    def __init__(self, total, quiet):
        self.bar = None
        if not quiet and sys.stderr.isatty() and total:
            from tqdm import tqdm
            self.bar = tqdm(total=total, unit="material", dynamic_ncols=True)

    def done(self, res):
        if self.bar:
            self.bar.set_postfix_str(f"{res.name} rmse_{res.metric} {res.errors['rmse_' + res.metric]:.4g}")
            self.bar.update(1)

    def close(self):
        if self.bar:
            self.bar.close()


def fit_all(source, out=None, options: FitOptions | None = None, batch=100, export=False,
            quiet=True, log=None, client=None, select_lobes=False, free_peak=False, **kw) -> RunReport:
    """Fit every material of a database; write results to ``out`` if given.

    ``source``: folder, file or list of files.  ``options`` or keyword arguments
    give the FitOptions.  ``client``: a dask.distributed Client to spread batches
    over workers (see brdfcl.cluster)."""
    opts = options or FitOptions(**kw)
    log = log or (lambda s: None)
    t0 = time.perf_counter()
    paths = database_paths(source)
    report = RunReport()
    fitter = None
    if out is not None:
        out = check_output_dir(out)
        remove_stale_temporaries(out)
    model_spec, todo = Model(opts.model, fixed=opts.fixed).spec, []
    for p in paths:
        if out is not None and is_finished(out, material_name(p), model_spec, opts.metric, select_lobes):
            report.resumed.append(material_name(p))
        else:
            todo.append(p)
    if report.resumed:
        log(f"resuming: {len(report.resumed)} materials already finished in {out}")
    if select_lobes:
        return _fit_selected(todo, out, opts, batch, export, report, log, t0, free_peak)
    if client is not None:
        from .cluster import fit_on_cluster
        return fit_on_cluster(client, todo, out, opts, batch, export, report, log, quiet, t0)
    progress = Progress(len(todo), quiet)
    try:
        for s in range(0, len(todo), batch):
            fitter = fitter or Fitter(opts)
            part = todo[s:s + batch]

            def on_error(item, e, part=part):
                path = getattr(item, "path", None) or str(item)
                report.skipped[path] = str(e)
                log(f"skipped: {e}")
            names, full, coarse = load_batch([FileReader(p) for p in part], fitter, on_error)
            if not names:
                continue
            log(f"batch of {len(names)} materials loaded")
            handle = result_writer(out, Models(opts, fitter.engine), export, report, progress)
            fitter.fit(names, full, coarse, on_result=handle, log=log)
    finally:
        finish_run(progress, out, report, t0)
    return report


def finish_run(progress, out, report, t0):
    """Close the progress bar, write summary.csv from what is on disk, time the run."""
    progress.close()
    if out is not None:
        write_summary(out)
    report.seconds = time.perf_counter() - t0


class FileReader:
    """Reads one file when called; named by its path so that errors can say which."""

    def __init__(self, path):
        self.path = path

    def __call__(self):
        if not os.path.exists(self.path):
            raise MerlError(f"{self.path}: file disappeared before it could be read")
        return read_merl(self.path)

    def __str__(self):
        return self.path


class Models:
    """Model, and compiled engine on demand, per model spec: what writing and exporting results
    need.  The fitted model carries the run's fixed parameters; selected sub-models have none."""

    def __init__(self, opts, engine=None):
        self.opts = opts
        main = Model(opts.model, fixed=opts.fixed)
        self._models = {main.spec: main}
        self._engines = {main.spec: engine} if engine is not None else {}

    def model(self, spec):
        if spec not in self._models:
            self._models[spec] = Model(spec)
        return self._models[spec]

    def engine(self, spec):
        if spec not in self._engines:
            o = self.opts
            self._engines[spec] = Engine(self.model(spec), device=o.device, real=o.real, metric=o.metric,
                                         cosw=o.cosw)
        return self._engines[spec]


def result_writer(out, models: Models, export, report, progress):
    """Record each result; with an output folder, write NAME.json (and NAME.binary) and summary.csv."""
    def handle(res, extra=None):
        report.results.append(res)
        if out is not None:
            write_result(out, result_document(res, models.model(res.model), extra))
            if export:
                export_fit(Path(out) / f"{res.name}.binary", models.engine(res.model), res.params)
            write_summary(out)
        progress.done(res)
    return handle


def _fit_selected(paths, out, opts, batch, export, report, log, t0, free_peak=False):
    """--select-lobes: the lobe comparison of brdfcl.analyze decides each material's model;
    its final fit (without the diffraction lobe where the verdict is 'none') is the result."""
    from .analyze import analyze
    write = result_writer(out, Models(opts), export, report, Progress(0, True))
    analyze(paths, None, opts, batch=batch, log=log, figures=False, ct_peak=not free_peak,
            on_material=lambda a: write(a.final, {"selected_by": "lobe comparison", "verdict": a.verdict}))
    report.seconds = time.perf_counter() - t0
    return report
