"""The writer protocol: what a run tells its writers, and what a writer does with it.

A run (brdfcl.app.runner) describes itself once as a `Job` (its kind, output folder, what the
user asked for, and how to get a model or a compiled engine for a model spec) and hands every
finished material to the writers as an `Item`.  A `Writer` has a ``name`` (its key in
brdfcl.report.writers.IMPLEMENTED_WRITERS) and four steps, each optional:

* ``applies_to(job)``: whether it takes part in this job at all;
* ``prepare(job)``: before any work (make and check its folders: a one-line OSError);
* ``write(job, item)``: as each material finishes (``job.items`` holds every item so far);
* ``finish(job, items)``: once, when the run has completed; returns the main file it wrote, if any.

An `ExportWriter` writes one file per fit for another program (``NAME.binary``, ``NAME.brdf``):
it runs in every fit job, writes its file when the user asked for it (``job.exports``) and
otherwise removes the file an earlier fit of the material left, so that no export outlives the
fit it tabulates; a resumed run writes a finished fit's missing export without refitting.
"""
from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from brdfcl.model.compose import Model
from brdfcl.report.output import result_document

if TYPE_CHECKING:                   # annotations only: writing a file never needs OpenCL
    from brdfcl.analysis.analyze import MaterialAnalysis
    from brdfcl.device.engine import Engine

FIT = "fit"                         # fit-all (in this process, on a cluster, --select-lobes)
ANALYSIS = "analysis"               # analyze
KINDS = (FIT, ANALYSIS)


def _quiet(message: str) -> None:
    """The default log: says nothing."""


@dataclass
class Item:
    """One finished material, as every writer sees it."""

    name: str
    table: str | None = None                  # the measured file it came from
    doc: dict | None = None                   # a fit: its NAME.json document (result_document)
    analysis: MaterialAnalysis | None = None  # an analysis: its tests, fits and verdict

    @classmethod
    def of_fit(cls, job: Job, res: Any, extra: dict | None = None) -> Item:
        """The item of a finished FitResult: its NAME.json document made once, for every writer
        (the run's options recorded in it, ``extra`` added, e.g. the verdict of --select-lobes,
        and ``"source"``, the absolute path of the measured file)."""
        lambdas = getattr(res, "lambdas", None)
        doc = result_document(res, job.model(res.model) if lambdas is None else job.model(res.model, lambdas),
                              extra, job.options)
        table = job.tables.get(res.name)
        if table is not None:                     # where an export finds the measured points again
            doc["source"] = os.path.abspath(table)
        return cls(res.name, table, doc)


@dataclass
class Job:
    """A run as its writers see it.  The runner fills it once; writers only read it (and
    ``items``, which the runner appends to before each ``write``)."""

    kind: str                                     # FIT or ANALYSIS
    out: Path                                     # the output folder, checked writable
    options: dict = field(default_factory=dict)   # a fit's recorded options (NAME.json "options")
    exports: frozenset[str] = frozenset()         # export writers asked for: "merl", "brdf_explorer"
    figures: bool = False                         # the analysis figures (PNG)
    pages: bool = False                           # the run's report, OUT/report/
    tables: dict[str, str] = field(default_factory=dict)     # material name -> measured file (any format)
    model: Callable[..., Model] = Model           # the Model of a spec (and wavelengths; the run's carries --fix)
    engine: Callable[[str], Engine] | None = None  # a compiled Engine of a spec (to tabulate fits)
    log: Callable[[str], None] = _quiet
    published: dict = field(default_factory=dict)  # material -> its best published fit (brdfcl.report.published)
    items: list[Item] = field(default_factory=list)   # finished so far, in order

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"job kind '{self.kind}'; valid: {', '.join(KINDS)}")


class Writer:
    """One output of a run (see the module's docstring).  Subclasses set ``name`` and override
    the steps they need; the defaults do nothing."""

    name: str = ""

    def applies_to(self, job: Job) -> bool:
        return True

    def prepare(self, job: Job) -> None:
        return None

    def write(self, job: Job, item: Item) -> None:
        return None

    def finish(self, job: Job, items: list[Item]) -> Path | None:
        return None


class ExportWriter(Writer):
    """A fitted model as ``NAME<suffix>`` for another program: ``export`` writes it."""

    suffix: str = ""

    def applies_to(self, job: Job) -> bool:
        return job.kind == FIT

    def path(self, out: Path, name: str) -> Path:
        return Path(out) / f"{name}{self.suffix}"

    def wanted(self, job: Job) -> bool:
        """The user asked for this export."""
        return self.name in job.exports

    def missing(self, job: Job, name: str) -> bool:
        """Asked for, and not there: a resumed run writes it without refitting."""
        return self.wanted(job) and not self.path(job.out, name).exists()

    def export(self, path: Path, doc: dict, job: Job) -> Path:
        """Write the fit of ``doc`` (a NAME.json document) to ``path``; returns the path."""
        raise NotImplementedError

    def write(self, job: Job, item: Item) -> None:
        assert item.doc is not None, "an export writes fits"
        path = self.path(job.out, item.name)
        if self.wanted(job) and len(item.doc.get("wavelengths_um") or (0, 0, 0)) != 3:
            job.log(f"{item.name}: no {self.name} export: it is a fit of {len(item.doc['wavelengths_um'])} "
                    f"spectral channels (fit with --rgb for an RGB model)")
        elif self.wanted(job):
            self.export(path, item.doc, job)
        elif path.is_file() and not path.is_symlink():      # it tabulates a fit this one replaces
            path.unlink()
