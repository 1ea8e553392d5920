"""NAME-mitsuba/: a fitted model as Mitsuba 3 scene files, the "brdfcl" BSDF and, where the fit maps
onto them, Mitsuba's own BSDFs (brdfcl.report.export.mitsuba_scene; ``brdfcl export --mitsuba``)."""
from __future__ import annotations

from pathlib import Path

from brdfcl.report.export.mitsuba_scene import write_mitsuba
from brdfcl.report.writers.base import ExportWriter, Job


class MitsubaExport(ExportWriter):
    """A folder: the fit, XML fragments and scenes, and Python dicts (nothing here imports Mitsuba)."""

    name = "mitsuba"
    suffix = "-mitsuba"

    def export(self, path: Path, doc: dict, job: Job) -> Path:
        written, mapping = write_mitsuba(path, doc)
        job.log(f"Mitsuba files in {path}: {', '.join(p.name for p in written)}")
        job.log(f"Mitsuba's own BSDFs: {mapping.note}")
        return path
