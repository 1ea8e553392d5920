"""NAME.binary: a fitted model tabulated as a MERL table (``fit-all --export-merl``, ``brdfcl
export --merl``), for any renderer that reads MERL data."""
from __future__ import annotations

from pathlib import Path

from brdfcl.report.output import export_fit
from brdfcl.report.writers.base import ExportWriter, Job


class MerlExport(ExportWriter):
    """The fit over the whole MERL table, computed by the job's engine for the fit's model."""

    name = "merl"
    suffix = ".binary"

    def export(self, path: Path, doc: dict, job: Job) -> Path:
        assert job.engine is not None, "a MERL export needs the job's engines"
        params = {k: v["value"] if isinstance(v, dict) else v for k, v in doc["params"].items()}
        export_fit(path, job.engine(doc["model"]), params)
        return path
