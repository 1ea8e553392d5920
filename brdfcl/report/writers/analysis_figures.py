"""figures/NAME_KIND.png: the analysis figures of each material: for a table the gradient test,
the wavelength check and the fitted components (brdfcl.report.figures); for scattered samples
the spectral wavelength check and measured against fitted in the plane of incidence
(brdfcl.report.sample_figures)."""
from __future__ import annotations

from pathlib import Path

from brdfcl.data.inputs import check_output_dir
from brdfcl.model.compose import Model
from brdfcl.report import figures, sample_figures
from brdfcl.report.files import remove_stale_temporaries
from brdfcl.report.writers.base import ANALYSIS, Item, Job, Writer

FIGURES = ("gradient", "wavelength", "components")      # figures.figure_<kind>, in page order
SAMPLE_FIGURES = ("spectral", "in_plane")                 # of scattered samples


def of_samples(analysis) -> bool:
    """An analysis of scattered samples (brdfcl.analysis.samples): it has no gradient test."""
    return getattr(analysis, "gradient", True) is None


def figure_kinds(analysis) -> tuple[str, ...]:
    """The figures of an analysis: of a table (FIGURES) or of scattered samples (SAMPLE_FIGURES,
    without the wavelength check where it could not be computed)."""
    if not of_samples(analysis):
        return FIGURES
    return SAMPLE_FIGURES if analysis.spectral is not None else SAMPLE_FIGURES[1:]


def figure_paths(out: Path, analysis) -> list[Path]:
    """Where a material's figures are, in page order (the index and the report link them)."""
    kinds = figure_kinds(analysis)
    return [Path(out) / "figures" / f"{analysis.name}_{k}.png" for k in kinds]


def draw(analysis, kind: str, path: Path) -> None:
    """Draw one figure of an analysis."""
    if kind == "in_plane":
        a = analysis
        final = a.final
        model = Model(final.model, lambdas=a.lambdas)
        sample_figures.figure_in_plane(a.samples, model, final.params, path,
                                       title=f"{a.name}: measured and fitted (final model {final.model}) "
                                             f"in the plane of incidence")
    elif kind == "spectral":
        sample_figures.figure_spectral(analysis, path)
    else:
        getattr(figures, f"figure_{kind}")(analysis, path)


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
            for path in figure_paths(job.out, a):
                draw(a, path.stem[len(a.name) + 1:], path)
