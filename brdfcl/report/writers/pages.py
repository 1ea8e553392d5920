"""OUT/report/: the run's report, a comparison page and a page per material
(brdfcl.report.view.pages), written once when the run has completed.

A fit job shows every material of its input that has a NAME.json in the output folder (those
fitted now and those resumed); an analysis shows each analysed material's final fit with its
verdict and, where drawn, its analysis figures.
"""
from __future__ import annotations

from pathlib import Path

from brdfcl._words import count
from brdfcl.data.merl import read_merl_cells
from brdfcl.report.output import read_results
from brdfcl.report.writers.analysis_figures import figure_paths
from brdfcl.report.writers.base import FIT, Item, Job, Writer


class ReportPages(Writer):
    """When the job asks for them (``job.pages``); last, as it shows what the others wrote."""

    name = "pages"

    def applies_to(self, job: Job) -> bool:
        return job.pages

    def finish(self, job: Job, items: list[Item]) -> Path | None:
        # local: the pages draw with matplotlib, which a run without them never loads
        from brdfcl.report.view.pages import Entry, write_report
        if job.kind == FIT:
            entries = [Entry.from_document(d, job.tables[d["material"]]) for d in read_results(job.out)
                       if d["material"] in job.tables]
            title = f"brdfcl fits in {job.out}"
        else:
            entries = [Entry.from_result(i.analysis.final, i.table, verdict=i.analysis.verdict,
                                         figures=figure_paths(job.out, i.analysis) if job.figures else [])
                       for i in items if i.analysis is not None]
            if not entries:
                return None
            title = f"brdfcl analysis of {count(len(entries), 'material')}"
        job.log(f"report: the pages of {count(len(entries), 'material')} "
                f"(images drawn where a fit or table changed)")
        index = write_report(job.out, entries, read_merl_cells, title=title, engine=job.engine)
        job.log(f"report: {index}")
        return index
