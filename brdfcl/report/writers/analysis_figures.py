"""figures/NAME_KIND.png: the analysis figures of each material (brdfcl.report.figures draws
them): the gradient test, the wavelength check and the fitted components."""
from __future__ import annotations

from pathlib import Path

from brdfcl.data.inputs import check_output_dir
from brdfcl.report import figures
from brdfcl.report.files import remove_stale_temporaries
from brdfcl.report.writers.base import ANALYSIS, Item, Job, Writer

FIGURES = ("gradient", "wavelength", "components")      # figures.figure_<kind>, in page order


def figure_paths(out: Path, name: str) -> list[Path]:
    """Where a material's figures are, in page order (the index and the report link them)."""
    return [Path(out) / "figures" / f"{name}_{k}.png" for k in FIGURES]


class AnalysisFigures(Writer):
    """The figures, when the job asks for them (``job.figures``); the folder in every analysis,
    checked writable before any work (the index links it)."""

    name = "figures"

    def applies_to(self, job: Job) -> bool:
        return job.kind == ANALYSIS

    def prepare(self, job: Job) -> None:
        remove_stale_temporaries(check_output_dir(job.out / "figures"))

    def write(self, job: Job, item: Item) -> None:
        a = item.analysis
        assert a is not None
        if job.figures:
            for kind, path in zip(FIGURES, figure_paths(job.out, a.name)):
                getattr(figures, f"figure_{kind}")(a, path)
