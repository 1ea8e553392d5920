"""NAME.alta: a fitted model as an ALTA data file (``brdfcl export --alta``), at the points of
the measurement it was fitted to, of another ALTA file (``--at``) or on a default grid
(brdfcl.report.export.alta gives the rule)."""
from __future__ import annotations

import os
from pathlib import Path

from brdfcl.report.export.alta import write_alta_fit
from brdfcl.report.writers.base import ExportWriter, Job


class AltaExport(ExportWriter):
    """The fit's float64 reference values, written in ALTA's text format; ``at``: an ALTA file
    whose points (parametrisation and outputs) the fit is written at."""

    name = "alta"
    suffix = ".alta"

    def __init__(self, at: str | os.PathLike[str] | None = None):
        self.at = at

    def export(self, path: Path, doc: dict, job: Job) -> Path:
        written, points = write_alta_fit(path, doc, self.at)
        job.log(f"{written}: at {points.origin}")
        return written
