"""NAME.brdf: a fitted model as a Disney BRDF Explorer file, analytic GLSL generated from the
terms' formulas (brdfcl.report.export.brdf_explorer; ``brdfcl export --brdf-explorer``)."""
from __future__ import annotations

from pathlib import Path

from brdfcl.report.export.brdf_explorer import write_brdf_explorer
from brdfcl.report.writers.base import ExportWriter, Job


class BrdfExplorerExport(ExportWriter):
    """The fit with its parameters as sliders (their bounds, the fitted values)."""

    name = "brdf_explorer"
    suffix = ".brdf"

    def export(self, path: Path, doc: dict, job: Job) -> Path:
        return write_brdf_explorer(path, doc)
