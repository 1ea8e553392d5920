"""A run's results as they arrive: recorded, written, counted, timed.

The one place where a fit-all run, in this process (brdfcl.app.run), on a Dask cluster
(brdfcl.app.cluster) or with the lobe comparison (--select-lobes), turns each finished FitResult into
its outputs: ``result_writer`` appends it to the ``RunReport``, writes NAME.json (with the options
that made it, brdfcl.report.output.recorded_options), NAME.binary when exporting, and summary.csv;
``Models`` holds the model, and the engine built on demand, that writing and exporting need per
model spec; ``Progress`` is the progress bar and ``finish_run`` closes a run.  Resuming,
batching and choosing where to fit stay in brdfcl.app.run, which imports this module from above.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from brdfcl.device.engine import Engine
from brdfcl.model.compose import Model
from brdfcl.optim.fit import Fitter
from brdfcl.report.output import export_fit, recorded_options, result_document, write_result, write_summary


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


class Progress:
    def __init__(self, total, quiet):
        self.bar = None
        if not quiet and sys.stderr.isatty() and total:
            self.bar = tqdm(total=total, unit="material", dynamic_ncols=True)

    def done(self, res):
        if self.bar:
            self.bar.set_postfix_str(f"{res.name} rmse_{res.metric} {res.errors['rmse_' + res.metric]:.4g}")
            self.bar.update(1)

    def close(self):
        if self.bar:
            self.bar.close()


def finish_run(progress, out, report, t0):
    """Close the progress bar, write summary.csv from what is on disk, time the run."""
    progress.close()
    if out is not None:
        write_summary(out)
    report.seconds = time.perf_counter() - t0


class Models:
    """Model, and compiled engine on demand, per model spec: what writing and exporting results
    need, with the options every result records (brdfcl.report.output.recorded_options).  The fitted
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
