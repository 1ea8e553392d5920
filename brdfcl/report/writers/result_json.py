"""NAME.json: one fit's document (brdfcl.report.output.result_document), what a resume reads."""
from __future__ import annotations

import json

from brdfcl.report.files import atomic_write_text
from brdfcl.report.writers.base import FIT, Item, Job, Writer


class ResultJson(Writer):
    """NAME.json per fitted material, indented one space (as every brdfcl before it)."""

    name = "json"

    def applies_to(self, job: Job) -> bool:
        return job.kind == FIT

    def write(self, job: Job, item: Item) -> None:
        assert item.doc is not None
        atomic_write_text(job.out / f"{item.name}.json", json.dumps(item.doc, indent=1))
