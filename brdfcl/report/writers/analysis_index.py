"""analysis.csv and index.html: every analysed material of the run, one row each.

analysis.csv has the columns of brdfcl.analysis.analyze.MaterialAnalysis.row; index.html shows
the main ones (short headers that wrap, the CSV name in a tooltip, so that the table fits a
page 1400 px wide) and then each material's figures.  Both are rewritten as each material
finishes, so that they are current whenever a run stops.
"""
from __future__ import annotations

import csv
import html
import io
import os
from pathlib import Path
from typing import Any

from brdfcl.report.files import atomic_write_text, writing
from brdfcl.report.writers.analysis_figures import figure_paths, of_samples
from brdfcl.report.writers.base import ANALYSIS, Item, Job, Writer

COLUMNS = ["material", "verdict", "verdict_by", "margin_gradient", "margin_wavelength", "margin_lobe",
           "margin_evidence", "selected_lobes", "grad_score_g", "grad_cells", "grad_band_deg_g",
           "law_ratio", "law_colour_ratio", "collapse_ratio", "lambda_exponent",
           "rmse_log_full", "rmse_log_no_diffraction", "rmse_log_no_ct",
           "peak_share_diffraction", "rmse_log_full_free", "peak_share_free"]
HEADS = {"verdict_by": "verdict hangs on", "margin_gradient": "margin gradient",
         "margin_wavelength": "margin wavelength", "margin_lobe": "margin lobe",
         "margin_evidence": "margin evidence", "selected_lobes": "lobes kept",
         "grad_score_g": "gradient score G", "grad_cells": "decided cells",
         "grad_band_deg_g": "band theta_h (deg) G", "law_ratio": "wavelength law ratio",
         "law_colour_ratio": "law ratio, colour",
         "collapse_ratio": "collapse ratio",
         "lambda_exponent": "lambda exponent (samples)",
         "rmse_log_full": "rmse_log full", "rmse_log_no_diffraction": "rmse_log no diffraction",
         "rmse_log_no_ct": "rmse_log no CT", "peak_share_diffraction": "peak share diffraction",
         "rmse_log_full_free": "rmse_log full, free peak", "peak_share_free": "peak share, free peak"}
STYLE = ("<style>body{font-family:sans-serif;margin:1em;max-width:1400px}td,th{border:1px solid #ccc;"
         "padding:2px 5px;font-size:13px}th{max-width:7em;vertical-align:bottom}table{border-collapse:collapse}"
         ".diffraction{background:#fde8d8}.none{background:#e3eefc}"
         ".figs img{display:block;width:100%;max-width:1400px;height:auto;margin:0.5em 0 1.5em}"
         "h2{margin-bottom:0.2em}</style>")
INTRO = ("<p>Gradient test: share of the decidable wide-angle cells whose data gradient at phi_d ~ 90 deg "
         "is closer to the diffraction prediction (parallel to grad f) than to the Cook-Torrance one "
         "(theta_h = const tilted by 1/(cos ti cos to) and the Fresnel slope of the ridge). "
         "Wavelength law: the full model fitted with each channel's wavelength and with every channel at "
         "one wavelength; the ratio of their RMS log errors over the wide-angle cells (or samples), &lt; 1 "
         "where the wavelength enters as diffraction predicts, read by the verdict as calibrated, the same "
         "for tables and scattered samples. Collapse ratio: spread of the channels' binned curves against "
         "f_c over their spread without the wavelength (&lt; 1 collapses), the law's picture, not read "
         "by the verdict. On scattered spectral samples the gradient test is not run (no grid); the "
         "fitted exponent n of the diffraction amplitude ~ lambda^-n is shown (4 in theory). Lobe "
         "comparison: penalised rmse_log with and without each lobe. Peak share: part of the fitted "
         "value at the specular peak carried by the diffraction lobe; the fits keep it at most equal to "
         "Cook-Torrance's (the talk's model), and the *_free columns show the full fit without that "
         "constraint. Margins: each test's signed distance to the calibrated threshold at which it "
         "contradicts diffraction, and (evidence) the larger distance of the gradient test and the law "
         "to the threshold at which they are evidence for it; positive on the side of diffraction; a "
         "verdict diffraction needs every margin positive (bench/results/calibration/NOTE.md: "
         "thresholds chosen on synthetic materials for at most 5% false positives in each class "
         "without diffraction).</p><table><tr>")


def write_index(out: str | os.PathLike, analyses: list[Any]) -> None:
    """analysis.csv and index.html of ``analyses`` (MaterialAnalysis, or anything with ``name``
    and ``row()``) in ``out``."""
    out = Path(out)
    rows = [a.row() for a in analyses]
    buf = io.StringIO()
    if rows:
        fields = list(dict.fromkeys(k for r in rows for k in r))     # tables and samples: the union
        w = csv.DictWriter(buf, fieldnames=fields, restval="", lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    with writing(out / "analysis.csv"):
        atomic_write_text(out / "analysis.csv", buf.getvalue())
    h = ["<!doctype html><meta charset='utf-8'><title>brdfcl analysis</title>", STYLE,
         "<h1>Diffraction in measured BRDFs: per-material verdicts</h1>", INTRO]
    h += [f"<th title='{c}'>{html.escape(HEADS.get(c, c))}</th>" for c in COLUMNS] + ["</tr>"]
    for a, r in zip(analyses, rows):
        cells = [f"<a href='#{html.escape(a.name)}'>{html.escape(a.name)}</a>"]
        cells += [html.escape(str(r.get(c, ""))).replace("+", "+<wbr>") for c in COLUMNS[1:]]
        h.append(f"<tr class='{r['verdict']}'>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    h.append("</table>")
    for a, r in zip(analyses, rows):
        h.append(f"<h2 id='{html.escape(a.name)}'>{html.escape(a.name)}: {r['verdict']}</h2>"
                 f"<p>lobes kept: {html.escape(r['selected_lobes'])}; final model: "
                 f"{html.escape(r['final_model'])}</p>")
        if of_samples(a):
            h.append(f"<p>{html.escape(r['data'])}; gradient test {html.escape(r['gradient_test'])}: the test on "
                     f"the model fitted to them would be no evidence, so the verdict rests on the lobe "
                     f"comparison and the wavelength law (fitted exponent of lambda "
                     f"{html.escape(r['lambda_exponent'] or 'n/a')} +- {html.escape(r['lambda_exponent_se'] or 'n/a')}"
                     f", theory 4 on a spectrally flat surface).</p>")
        h.append("<div class='figs'>")
        for p in figure_paths(Path(), a):     # relative: figures/NAME_KIND.png
            h.append(f"<a href='{p.as_posix()}'><img src='{p.as_posix()}' alt='{p.stem}'></a>")
        h.append("</div>")
    with writing(out / "index.html"):
        atomic_write_text(out / "index.html", "\n".join(h))


class AnalysisIndex(Writer):
    name = "index"

    def applies_to(self, job: Job) -> bool:
        return job.kind == ANALYSIS

    def write(self, job: Job, item: Item) -> None:
        write_index(job.out, [i.analysis for i in job.items if i.analysis is not None])
