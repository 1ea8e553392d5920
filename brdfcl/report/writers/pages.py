"""OUT/report/: the run's report, a comparison page and a page per material
(brdfcl.report.view.pages), written once when the run has completed.

A fit job shows every material of its input that has a NAME.json in the output folder (those
fitted now and those resumed); an analysis shows each analysed material's final fit with its
verdict and, where drawn, its analysis figures.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from brdfcl._words import count
from brdfcl.data.errors import DataError
from brdfcl.data.geometry import table_values
from brdfcl.data.merl import MerlError
from brdfcl.data.readers import read_measurement
from brdfcl.model.synth import truth_of
from brdfcl.report.output import read_results
from brdfcl.report.writers.analysis_figures import figure_paths
from brdfcl.report.writers.base import FIT, Item, Job, Writer

if TYPE_CHECKING:
    from brdfcl.report.view.images import Beside


class ReportPages(Writer):
    """When the job asks for them (``job.pages``); last, as it shows what the others wrote."""

    name = "pages"

    def __init__(self):
        self._beside: dict[Path, Beside] = {}    # a fit job's output folder -> its image workers

    def applies_to(self, job: Job) -> bool:
        return job.pages

    def prepare(self, job: Job) -> None:
        """A fit job: the image workers start now and draw the tables' measured side beside the
        fits (brdfcl.report.view.images.Beside)."""
        if job.kind != FIT:
            return
        from brdfcl.report.view.images import Beside
        tables = {n: p for n, p in job.tables.items() if _tabulated(p)}
        self._beside[job.out] = Beside(job.out / "report", tables, _read_cells)

    def finish(self, job: Job, items: list[Item]) -> Path | None:
        beside = self._beside.pop(job.out, None)
        try:
            return self._write(job, items, beside)
        finally:
            if beside is not None:
                beside.close()

    def _write(self, job: Job, items: list[Item], beside: Beside | None) -> Path | None:
        # local: the pages draw with matplotlib, which a run without them never loads
        from brdfcl.report.view.pages import Entry, write_report
        if job.kind == FIT:
            entries = [Entry.from_document(d, path, tabulated=_tabulated(path), truth=truth_of(path),
                                           published=job.published.get(d["material"]))
                       for d in read_results(job.out) if (path := job.tables.get(d["material"])) is not None]
            title = f"brdfcl fits in {job.out}"
        else:
            entries = [Entry.from_result(i.analysis.final, i.table, verdict=i.analysis.verdict,
                                         tabulated=_tabulated(i.table), truth=truth_of(i.table),
                                         figures=figure_paths(job.out, i.analysis) if job.figures else [])
                       for i in items if i.analysis is not None]
            if not entries:
                return None
            title = f"brdfcl analysis of {count(len(entries), 'material')}"
        job.log(f"report: the pages of {count(len(entries), 'material')} "
                f"(images drawn where a fit or table changed)")
        index = write_report(job.out, entries, _read_cells, title=title, engine=job.engine, beside=beside)
        job.log(f"report: {index}")
        return index


def _tabulated(path) -> bool:
    """Whether the measurement at ``path`` is a table (a dense layout: spheres and slices drawn
    from it); False for scattered samples and for a file that can no longer be read."""
    try:
        return read_measurement(path).layout.dense
    except (DataError, MerlError, OSError, ValueError):
        return False


def _read_cells(path, index):
    """A table's BRDF at the MERL table's cells ``index`` (the views')."""
    return table_values(read_measurement(path), index)
