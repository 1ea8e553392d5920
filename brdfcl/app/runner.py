"""The one job runner: what fit-all, analyze and cluster runs share, written once.

A `Runner` lists a job's input (brdfcl.data.inputs.database_paths) and, before any work, refuses
an output folder that is, holds or is inside the input or that cannot be written, removes what a
killed run left half-written, and lets the writers that apply to the job (brdfcl.report.writers)
prepare their folders.  The job reads its measurements (`read`: any format brdfcl.data.readers
reads, grouped by what can share a batch) and fits them in batches (`batches`, `fit_batch`): a
file that cannot be read is skipped with its one-line reason (`skip`: recorded in the RunReport and told to
``on_skip``, by default the log); each finished material goes to every writer and advances the
progress bar (`done`, `fitted`); `finish` lets the writers finish (summary.csv, the report pages)
and times the run.  Resuming a fit job is brdfcl.app.resume.

What differs between jobs is only how a batch is fitted: in this process (brdfcl.app.run), on a
Dask cluster (brdfcl.app.cluster) or through the lobe comparison (brdfcl.app.analyze).  `Models`
gives the writers the model, and the compiled engine on demand, of each model spec.
"""
from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from tqdm import tqdm

from brdfcl._words import count
from brdfcl.data.errors import DataError
from brdfcl.data.inputs import check_output_dir, check_output_not_input, database_paths
from brdfcl.data.measurement import Measurement
from brdfcl.data.merl import MerlError, material_name
from brdfcl.data.readers import read_measurement
from brdfcl.data.rgb import to_rgb
from brdfcl.device.engine import Engine
from brdfcl.model.compose import Model
from brdfcl.optim.fit import FitOptions, Fitter
from brdfcl.optim.forms import FormFitter
from brdfcl.report.files import remove_stale_temporaries
from brdfcl.report.output import recorded_options
from brdfcl.report.writers import Item, Job, Writer, writers_for

T = TypeVar("T")


def _quiet(message: str) -> None:
    """The default log: says nothing."""


@dataclass
class RunReport:
    """What a fit job returns (``fit_all``)."""

    results: list = field(default_factory=list)       # FitResult of the materials fitted now
    resumed: list = field(default_factory=list)       # names already finished in the output folder
    skipped: dict = field(default_factory=dict)       # path -> reason
    seconds: float = 0.0                              # until the last material (not the report pages)
    outputs: dict = field(default_factory=dict)       # writer name -> the file its finish wrote

    @property
    def ok(self) -> bool:
        return not self.skipped and all(r.success for r in self.results)

    @property
    def pages(self) -> Path | None:
        """The run's report page (OUT/report/index.html), when written."""
        return self.outputs.get("pages")


class Progress:
    """A progress bar on a terminal, one step per finished material; nothing otherwise."""

    def __init__(self, total: int, quiet: bool):
        self.bar = None
        if not quiet and sys.stderr.isatty() and total:
            self.bar = tqdm(total=total, unit="material", dynamic_ncols=True)

    def done(self, name: str, note: str = "") -> None:
        if self.bar:
            self.bar.set_postfix_str(f"{name} {note}".strip())
            self.bar.update(1)

    def close(self) -> None:
        if self.bar:
            self.bar.close()


class Models:
    """Model, and compiled engine on demand, per model spec: what writing and exporting results
    need, with the options every result records (brdfcl.report.output.recorded_options).  The fitted
    model carries the run's fixed parameters; selected sub-models have none."""

    def __init__(self, opts: FitOptions, engine: Engine | None = None, select_lobes: bool = False,
                 free_peak: bool = False, forms: dict | None = None):
        self.opts = opts
        self.options = recorded_options(opts, select_lobes, free_peak)
        self.forms = forms or None
        if forms:           # the candidates the choice was among (only then recorded)
            self.options["forms"] = sorted(forms)
        main = Model(opts.model, fixed=opts.fixed)
        self.main = main.spec
        self._models: dict[Any, Model] = {main.spec: main}
        self._engines = {main.spec: engine} if engine is not None else {}
        self._fitter: Fitter | None = None
        self._fitters: dict[tuple, Fitter] = {}
        self._form_fitters: dict[tuple | None, FormFitter] = {}

    def main_fitter(self) -> Fitter:
        """The Fitter of the run's model; exports of that model share its engine (built once)."""
        if self._fitter is None:
            self._fitter = Fitter(self.opts, engine=self._engines.get(self.main))
            self._engines[self.main] = self._fitter.engine
        return self._fitter

    def fitter(self, lambdas: tuple | None = None) -> Fitter | FormFitter:
        """What fits a batch of measurements in these channels (None: the model's own R, G, B):
        the run's model, or its choice of forms (built once each; exports of the R, G, B model and
        forms share their engines)."""
        key = None if lambdas is None or tuple(lambdas) == tuple(self._models[self.main].lambdas) else tuple(lambdas)
        if self.forms is None:
            if key is None:
                return self.main_fitter()
            if key not in self._fitters:
                self._fitters[key] = Fitter(self.opts, lambdas=key)
            return self._fitters[key]
        if key not in self._form_fitters:
            ff = self._form_fitters[key] = FormFitter(self.opts, self.forms, lambdas=key)
            if key is None:
                for k, f in ff.fitters.items():
                    self._engines.setdefault(ff.forms[k], f.engine)
        return self._form_fitters[key]

    def model(self, spec: str, lambdas: tuple | None = None) -> Model:
        """The model of a spec (with the run's fixed parameters for its own), at ``lambdas`` (one
        wavelength per channel; default the R, G, B of MERL tables)."""
        if lambdas is not None:
            key = (spec, tuple(lambdas))
            if key not in self._models:
                fixed = self.opts.fixed if spec == self.main else None
                self._models[key] = Model(spec, fixed=fixed, lambdas=tuple(lambdas))
            return self._models[key]
        if spec not in self._models:
            self._models[spec] = Model(spec)
        return self._models[spec]

    def engine(self, spec: str) -> Engine:
        if spec == self.main and spec not in self._engines:
            return self.main_fitter().engine
        if spec not in self._engines:
            o = self.opts
            self._engines[spec] = Engine(self.model(spec), device=o.device, real=o.real, metric=o.metric,
                                         cosw=o.cosw, vector_width=getattr(o, "vector_width", None))
        return self._engines[spec]


class Runner:
    """One run of a job (see the module's docstring).  ``out`` None: nothing is written, the
    results are only returned; ``job`` holds the Job's other fields (brdfcl.report.writers.Job)."""

    def __init__(self, source: Any, out: str | os.PathLike | None, kind: str, *,
                 log: Callable[[str], None] | None = None,
                 on_skip: Callable[[str, str], None] | None = None, quiet: bool = True, **job: Any):
        self.t0 = time.perf_counter()
        self.log = log or _quiet
        self.on_skip = on_skip or (lambda path, why: self.log(f"skipped: {why}"))
        self.quiet = quiet
        self.paths = database_paths(source)
        self.report = RunReport()
        self.paths = self._one_per_name(self.paths)
        self.progress = Progress(0, True)
        self.job: Job | None = None
        self.writers: list[Writer] = []
        if out is not None:                     # one-line errors, before any work
            check_output_not_input(source, out, self.paths)
            checked = check_output_dir(out)
            remove_stale_temporaries(checked)
            tables = {material_name(p): p for p in self.paths}     # tables and samples files
            self.job = Job(kind, checked, tables=tables, log=self.log, **job)
            self.writers = writers_for(self.job)
            for w in self.writers:
                w.prepare(self.job)

    def _one_per_name(self, paths: list[str]) -> list[str]:
        """The paths with distinct material names: one result per name (NAME.json), so a second
        file of a name (krylon.brdf beside krylon.csv) is skipped with its reason."""
        first: dict[str, str] = {}
        kept = []
        for p in paths:
            name = material_name(p)
            if name in first:
                self.skip(p, f"{p}: material name '{name}' already taken by {first[name]} (one result per name; "
                             f"rename one file to fit both)")
                continue
            first[name] = p
            kept.append(p)
        return kept

    @staticmethod
    def batches(paths: Sequence[T], size: int) -> Iterator[Sequence[T]]:
        for s in range(0, len(paths), size):
            yield paths[s:s + size]

    @contextmanager
    def tracking(self, total: int) -> Iterator[None]:
        """A progress bar over ``total`` materials while the job fits (closed however it ends)."""
        self.progress = Progress(total, self.quiet)
        try:
            yield
        finally:
            self.progress.close()

    def skip(self, path: str, why: object) -> None:
        """A file that cannot be read: recorded with its reason, and told."""
        self.report.skipped[str(path)] = str(why)
        self.on_skip(str(path), str(why))

    def read(self, paths: Sequence[str], rgb: bool = False) -> list[list[Measurement]]:
        """The measurements of ``paths`` (brdfcl.data.readers.read_measurement; ``rgb``: spectral
        ones as linear sRGB, brdfcl.data.rgb.to_rgb), in groups that can share a batch
        (``Measurement.batch_key``: the same channels, a table format's one layout); a file that
        cannot be read is skipped with its reason."""
        groups: dict[tuple, list[Measurement]] = {}
        for p in paths:
            try:
                m = read_measurement(p)
                if rgb:
                    m = to_rgb(m)
            except (DataError, MerlError, ValueError) as e:
                self.skip(p, e)
                continue
            except ImportError as e:        # --rgb without colour-science: one line for the whole run
                raise ValueError(str(e)) from None
            groups.setdefault(m.batch_key(), []).append(m)
        return list(groups.values())

    def fit_batch(self, fitter: Fitter | FormFitter, part: Sequence[Measurement],
                  on_result: Callable[[Any, dict | None], None] | None = None) -> Sequence[tuple[Any, dict | None]]:
        """Fit one batch (a file that cannot be read now is skipped with its reason): [(result, what
        NAME.json records beside it: the form chosen, or None)], each told to ``on_result`` (default
        `fitted`) as it finishes."""
        on_result = on_result or self.fitted

        def skip(m: Measurement, e: Exception) -> None:
            self.skip(m.path or m.name, e)
        bands = part[0].n_channels if part else 0
        self.log(f"batch of {count(len(part), 'material')} ({count(bands, 'channel')})")
        if isinstance(fitter, FormFitter):
            return fitter.fit(part, on_result=on_result, log=self.log, on_error=skip)
        return [(r, None) for r in fitter.fit(part, on_result=lambda r: on_result(r, None), log=self.log,
                                                on_error=skip)]

    def done(self, item: Item, note: str = "") -> None:
        """A finished material: to every writer, and one step of the progress bar."""
        if self.job is not None:
            self.job.items.append(item)
            for w in self.writers:
                w.write(self.job, item)
        self.progress.done(item.name, note)

    def fitted(self, res: Any, extra: dict | None = None) -> None:
        """A finished FitResult (``extra``: recorded beside it in NAME.json)."""
        self.report.results.append(res)
        item = Item.of_fit(self.job, res, extra) if self.job is not None else Item(res.name)
        self.done(item, f"rmse_{res.metric} {res.errors['rmse_' + res.metric]:.4g}")

    def finish(self) -> RunReport:
        """The run has completed: time it, then let every writer finish."""
        self.report.seconds = time.perf_counter() - self.t0
        if self.job is not None:
            for w in self.writers:
                made = w.finish(self.job, self.job.items)
                if made is not None:
                    self.report.outputs[w.name] = made
        return self.report
