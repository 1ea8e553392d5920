"""Every output of a run is a writer, registered in one table (as scipy.optimize's
``IMPLEMENTED_LOSSES``): the job runner (brdfcl.app.runner) calls the writers that apply to its
job, in the table's order, and nothing else writes a run's files.

``IMPLEMENTED_WRITERS`` maps each writer's name to it.  The protocol (brdfcl.report.writers.base):
``applies_to(job)``, ``prepare(job)`` before any work, ``write(job, item)`` as each material
finishes, ``finish(job, items)`` when the run has completed.  A writer that reads what another
writes comes after it (summary.csv reads every NAME.json; the report pages show everything).
Adding an output is one file defining a Writer and one line in the table (docs/howto.md);
tests/test_writers.py then runs it on a fit job.
"""
from __future__ import annotations

from brdfcl.report.writers.alta import AltaExport
from brdfcl.report.writers.analysis_figures import AnalysisFigures
from brdfcl.report.writers.analysis_index import AnalysisIndex
from brdfcl.report.writers.analysis_maps import AnalysisMaps
from brdfcl.report.writers.base import ANALYSIS, FIT, ExportWriter, Item, Job, Writer
from brdfcl.report.writers.brdf_explorer import BrdfExplorerExport
from brdfcl.report.writers.merl import MerlExport
from brdfcl.report.writers.mitsuba import MitsubaExport
from brdfcl.report.writers.pages import ReportPages
from brdfcl.report.writers.result_json import ResultJson
from brdfcl.report.writers.summary import SummaryCsv

IMPLEMENTED_WRITERS: dict[str, Writer] = {w.name: w for w in (
    ResultJson(),               # NAME.json                 fit jobs
    MerlExport(),               # NAME.binary               fit jobs, --export-merl
    BrdfExplorerExport(),       # NAME.brdf                 fit jobs, export="brdf_explorer"
    MitsubaExport(),            # NAME-mitsuba/             fit jobs, export="mitsuba"
    AltaExport(),               # NAME.alta                 fit jobs, export="alta"
    SummaryCsv(),               # summary.csv               fit jobs (reads every NAME.json)
    AnalysisMaps(),             # NAME.exr                  analyses
    AnalysisFigures(),          # figures/NAME_KIND.png     analyses, unless --no-figures
    AnalysisIndex(),            # analysis.csv, index.html  analyses
    ReportPages(),              # report/                   unless --no-report
)}


def writers_for(job: Job) -> list[Writer]:
    """The registered writers that take part in ``job``, in the table's order."""
    return [w for w in IMPLEMENTED_WRITERS.values() if w.applies_to(job)]


def export_writers() -> dict[str, ExportWriter]:
    """The registered exports by name (what ``fit_all(export=...)`` may ask for)."""
    return {n: w for n, w in IMPLEMENTED_WRITERS.items() if isinstance(w, ExportWriter)}


__all__ = ["ANALYSIS", "FIT", "IMPLEMENTED_WRITERS", "ExportWriter", "Item", "Job", "Writer", "export_writers",
           "writers_for"]
