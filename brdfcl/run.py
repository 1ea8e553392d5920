"""A database fit as a user runs it: resume, batches, bad files, outputs as results arrive.

``fit_all`` is the Python API behind ``brdfcl fit-all``.  Materials are fitted in
batches (all materials of a batch share every launch); each finished material
is written at once (NAME.json, optionally NAME.binary with the fitted model),
and summary.csv is rewritten from every NAME.json in the output folder.

Input data is read-only: an output folder that is, holds or is inside the input folder, or
holds an input file (symlinks resolved), is refused before any work
(``check_output_not_input``).  Re-running into an output folder reuses a finished result only
if it was made with the same options (brdfcl.output.resume_state); a result of other options
stops the run before any work (``ResultsDiffer``) unless ``overwrite``.  A finished fit whose
export is missing is exported without refitting.
"""
from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path


from .engine import Engine
from .fit import FitOptions, Fitter, load_batch
from .merl import MerlError, list_database, material_name, read_merl
from .model import Model
from .output import (export_fit, read_results, recorded_options, remove_stale_temporaries, result_document,
                     resume_state, write_result, write_summary)


class InputOverwriteError(ValueError):
    """An output that would be, hold or sit inside the input data (brdfcl never writes there)."""


class ResultsDiffer(ValueError):
    """The output folder holds results made with other options than this run's."""


# CLI flags of recorded options, for messages (a dotted name first, then its first part)
OPTION_FLAGS = {"model": "--model", "metric": "--metric", "cosw": "--no-cos", "cutoff_deg": "--cutoff",
                "real": "--double", "global_method": "--global", "n_candidates": "--candidates",
                "n_starts": "--starts", "lm.max_iter": "--max-iter", "seed": "--seed", "fixed": "--fix",
                "ct_peak": "--ct-peak", "select_lobes": "--select-lobes", "free_peak": "--free-peak"}


@dataclass
class RunReport:
    results: list = field(default_factory=list)       # FitResult of the materials fitted now
    resumed: list = field(default_factory=list)       # names already finished in the output folder
    skipped: dict = field(default_factory=dict)       # path -> reason
    seconds: float = 0.0
    pages: Path | None = None                         # the run's report page, when written

    @property
    def ok(self):
        return not self.skipped and all(r.success for r in self.results)


def database_paths(source) -> list[str]:
    """A folder (its .binary files), a single file, or a list of files."""
    if isinstance(source, (str, os.PathLike)):
        return [os.fspath(source)] if os.path.isfile(source) else list_database(source)
    return [os.fspath(p) for p in source]


def _forms(path):
    """A path as given (absolute, normalised) and with every symlink resolved."""
    return {os.path.abspath(path), os.path.realpath(path)}


def _within(a, b):
    """a is b or inside it."""
    return a == b or os.path.commonpath([a, b]) == b


def check_output_not_input(source, out, paths=None):
    """Refuse (InputOverwriteError, one line) an output folder that is, is inside or holds the input
    folder, or that is or holds an input file; paths as given and with symlinks resolved (a
    folder of links: the links' targets are inputs too).  ``source``: folder, file or list of
    files as for fit_all; ``paths``: its files if already listed.  Call before any work
    (fit_all and brdfcl.analyze do)."""
    paths = database_paths(source) if paths is None else paths
    outs = _forms(out)
    if isinstance(source, (str, os.PathLike)) and os.path.isdir(source):
        for f in sorted(_forms(source)):
            for o in sorted(outs):
                how = ("is the input folder" if o == f else "is inside the input folder" if _within(o, f)
                       else "holds the input folder" if _within(f, o) else None)
                if how:
                    _refuse(out, how, f)
    for p in paths:
        files = _forms(p) | {os.path.join(os.path.realpath(os.path.dirname(os.path.abspath(p))),
                                          os.path.basename(p))}
        for f in sorted(files):
            for o in sorted(outs):
                if _within(f, o):
                    _refuse(out, "is the input file" if o == f else "holds the input file", f)


def _refuse(out, how, what):
    raise InputOverwriteError(f"output folder {out} {how} {what}: input data is read-only to brdfcl; "
                              f"choose an output folder outside the input data")


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
            quiet=True, log=None, client=None, select_lobes=False, free_peak=False, overwrite=False,
            pages=False, **kw) -> RunReport:
    """Fit every material of a database; write results to ``out`` if given.

    ``source``: folder, file or list of files.  ``options`` or keyword arguments
    give the FitOptions.  ``client``: a dask.distributed Client to spread batches
    over workers (see brdfcl.cluster).  ``out`` may not be, hold or be inside the input
    (InputOverwriteError).  Results already in ``out`` are reused when made with the same
    options; results of other options raise ResultsDiffer before any work, or with
    ``overwrite`` are refitted and replaced.  ``pages``: write the run's report
    (``OUT/report/index.html``, brdfcl.view.pages) at the end (the CLI does unless --no-report)."""
    opts = options or FitOptions(**kw)
    log = log or (lambda s: None)
    t0 = time.perf_counter()
    paths = database_paths(source)
    report = RunReport()
    if select_lobes:        # what the lobe comparison fits with (brdfcl.analyze), so what is recorded
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
        from .cluster import fit_on_cluster
        fit_on_cluster(client, todo, out, opts, batch, export, report, log, quiet, t0)
    else:
        _fit_here(todo, out, models, batch, export, report, log, quiet, t0)
    if out is not None and pages:
        report.pages = write_pages(out, paths, log)
    return report


def write_pages(out, paths, log=None):
    """The run's report for the materials of ``paths`` that have a result in ``out``."""
    from .view.pages import Entry, write_report      # matplotlib only when pages are written
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
    need, with the options every result records (brdfcl.output.recorded_options).  The fitted
    model carries the run's fixed parameters; selected sub-models have none."""

    def __init__(self, opts, engine=None, select_lobes=False, free_peak=False):
        self.opts = opts
        self.options = recorded_options(opts, select_lobes, free_peak)
        main = Model(opts.model, fixed=opts.fixed)
        self.main = main.spec
        self._models = {main.spec: main}
        self._engines = {main.spec: engine} if engine is not None else {}
        self._fitter = None

    def main_fitter(self):
        """The Fitter of the run's model; exports of that model share its engine (built once)."""
        if self._fitter is None:
            self._fitter = Fitter(self.opts, engine=self._engines.get(self.main))
            self._engines[self.main] = self._fitter.engine
        return self._fitter

    def model(self, spec):
        if spec not in self._models:
            self._models[spec] = Model(spec)
        return self._models[spec]

    def engine(self, spec):
        if spec == self.main and spec not in self._engines:
            return self.main_fitter().engine
        if spec not in self._engines:
            o = self.opts
            self._engines[spec] = Engine(self.model(spec), device=o.device, real=o.real, metric=o.metric,
                                         cosw=o.cosw, vector_width=getattr(o, "vector_width", None))
        return self._engines[spec]


def result_writer(out, models: Models, export, report, progress):
    """Record each result; with an output folder, write NAME.json (with the options that made it)
    and NAME.binary (removing an earlier fit's NAME.binary without export), then summary.csv.
    ``out`` has passed check_output_not_input (fit_all, before any work)."""
    options = {**models.options, "export": bool(export)}

    def handle(res, extra=None):
        report.results.append(res)
        if out is not None:
            binary = Path(out) / f"{res.name}.binary"
            write_result(out, result_document(res, models.model(res.model), extra, options))
            if export:
                export_fit(binary, models.engine(res.model), res.params)
            elif binary.is_file() and not binary.is_symlink():  # tabulates a fit this one replaces
                binary.unlink()
            write_summary(out)
        progress.done(res)
    return handle


def _fit_selected(paths, out, opts, batch, export, report, log, t0, models):
    """--select-lobes: the lobe comparison of brdfcl.analyze decides each material's model;
    its final fit (without the diffraction lobe where the verdict is 'none') is the result."""
    from .analyze import analyze
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
