"""brdfcl's fits against the published fits of the field, side by side on the same tables.

Every material of the set is fitted by brdfcl (one batch per model, default options, the whole
fit timed), and every fit, brdfcl's and the published ones of `published.py` (SGD, Bagher et al.
2012; ABC microfacet and smooth surface, Löw et al. 2012, E2 fits), is scored by one function on
the same cells: ``rmse_log`` of brdfcl.model.metrics.errors, the solid-angle weighted RMS of
ln(1 + f cos theta_i) - ln(1 + f_measured cos theta_i) over every cell with theta_i, theta_o
(and the fit's cut-off) below 80 degrees, the E2 metric of Löw et al. with MERL's bin weights.
brdfcl's fits are evaluated by its float64 kernels (equal to the float64 reference to ~1e-15)
and scored by the same host function as the published ones.

Reported per material: each score, and the ratio of brdfcl's to the best published one (the
better of SGD and the two ABC fits); the median ratio, the materials where brdfcl is worse, and
the time of each whole-database fit.  The published fits were made on measured MERL; on
MERL-proxy tables they are evaluated on data they were not fitted to, so the comparison is fair
only in direction: a proxy is smooth where MERL is noisy.
"""
from __future__ import annotations

import csv
import datetime
import json
import time
from pathlib import Path

import numpy as np
import published
from bench_stages import cpu_name

from brdfcl import __version__
from brdfcl.data.geometry import DEFAULT_CUTOFF_DEG, table_geometry
from brdfcl.data.merl import read_merl
from brdfcl.device.engine import Engine, select_cells
from brdfcl.model.compose import DEFAULT_MODEL, Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.metrics import errors
from brdfcl.optim.fit import FitOptions, Fitter
from brdfcl.optim.forms import DEFAULT_FORMS, FormFitter, form_keys, resolve

PUBLISHED = ("sgd_bagher2012", "abc_low2012_microfacet_e2", "abc_low2012_smooth_e2")
SHORT = {"sgd_bagher2012": "SGD", "abc_low2012_microfacet_e2": "ABC-mf", "abc_low2012_smooth_e2": "ABC-sm"}


DEFAULT = "default"
"""What `brdfcl fit-all` fits when no model is given: DEFAULT_FORMS of the default model, each
material's form chosen (brdfcl.optim.forms.FormFitter)."""


def fit_database(tables: list, spec: str) -> tuple[dict[str, tuple[str, np.ndarray]], float]:
    """brdfcl's fit of every table (one batch, default options; ``spec`` DEFAULT: the fit-all
    default's choice of forms): {material: (its model, parameter values)}, and the wall time of the
    fit (extraction and upload included, reading the files not)."""
    t0 = time.perf_counter()
    if spec == DEFAULT:
        ff = FormFitter(FitOptions(), form_keys(DEFAULT_MODEL, resolve("default", FitOptions())))
        res = [r for r, _ in ff.fit(tables)]
    else:
        res = Fitter(FitOptions(model=spec)).fit(tables)
    seconds = time.perf_counter() - t0
    return {r.name: (r.model, np.array([r.params[n] for n in Model(r.model).names])) for r in res}, seconds


def score(tables: list, specs: list[str], fits: dict[str, dict[str, tuple[str, np.ndarray]]]) \
        -> dict[str, dict[str, float]]:
    """{material: {fit: rmse_log}} for brdfcl's fits ``specs`` (each material's model and values)
    and every published model, on the cells a default fit uses."""
    g = table_geometry()
    idx = select_cells(DEFAULT_CUTOFF_DEG)
    cells = Cells.from_geometry(g, idx)
    wi, wo, w, cw = g.wi[idx], g.wo[idx], g.weight[idx], cells.ci
    engines: dict[str, tuple] = {}

    def predict(model: str, values: np.ndarray) -> np.ndarray:
        if model not in engines:
            e = Engine(model, real="double")
            engines[model] = (e, e.upload([], idx, np.zeros((0, e.model.n_channels, idx.size), e.dtype)))
        e, cs = engines[model]
        return e.predict(cs, values)[0]
    out: dict[str, dict[str, float]] = {}
    for table in tables:
        m = table.brdf()[:, idx].astype(np.float64)
        row = {}
        for s in specs:
            row[s] = errors(predict(*fits[s][table.name]), m, w, cw)["rmse_log"]
        for name in PUBLISHED:
            if table.name in published.load(name):
                row[name] = errors(published.evaluate(name, table.name, wi, wo), m, w, cw)["rmse_log"]
        out[table.name] = row
    return out


def compare(paths: list[Path], specs: list[str], out: Path, data_label: str) -> str:
    """Fit, score and write published.json (the scores and times), published.csv and published.md
    into ``out``; returns the Markdown.  The files are read once, for every fit and the scores."""
    tables = [read_merl(p) for p in paths]
    fits, seconds = {}, {}
    for s in specs:
        fits[s], seconds[s] = fit_database(tables, s)
        print(f"{s}: {len(paths)} materials fitted in {seconds[s]:.1f} s", flush=True)
    models = {s: {n: m for n, (m, _) in f.items()} for s, f in fits.items() if s == DEFAULT}
    run = {"specs": specs, "seconds": seconds, "scores": score(tables, specs, fits), "data": data_label,
           "models": models,
           "cpu": cpu_name(), "date": str(datetime.date.today()), "version": __version__}
    (out / "published.json").write_text(json.dumps(run, indent=1))
    return report(out)


def _summary(specs: list[str], scores: dict, seconds: dict, rivals: tuple[str, ...]) -> list[str]:
    names = sorted(n for n in scores if any(k in scores[n] for k in rivals))     # those with a published fit
    best = {n: min(scores[n][k] for k in rivals if k in scores[n]) for n in names}
    rows = []
    for s in specs:
        ratio = np.array([scores[n][s] / best[n] for n in names])
        worse = [f"{n} ({r:.2f})" for n, r in zip(names, ratio) if r > 1]
        rows.append(f"| `{s}` | {seconds[s]:.1f} | {np.median(ratio):.3f} | {np.mean(ratio <= 0.7):.0%} | "
                    f"{len(worse)} of {len(names)}{': ' + ', '.join(worse) if worse else ''} |")
    return rows


def report(out: Path) -> str:
    """published.md and published.csv from published.json (``--published --report-only``)."""
    run = json.loads((out / "published.json").read_text())
    specs, scores, seconds = run["specs"], run["scores"], run["seconds"]
    names = sorted(scores)
    with open(out / "published.csv", "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["material", *specs, *PUBLISHED])
        for n in names:
            wr.writerow([n] + [f"{scores[n].get(k, np.nan):.6g}" for k in (*specs, *PUBLISHED)])
    head = ("| brdfcl model | whole-database fit (s) | median ratio | materials with ratio <= 0.7 | "
            "materials where brdfcl is worse (ratio) |")
    lines = [f"# brdfcl against the published fits ({run['date']})", "",
             f"Made by `python bench/bench_fit.py --published` (bench/compare_published.py). Data: {run['data']}, "
             f"{len(names)} materials. CPU: {run['cpu']}; brdfcl {run['version']}, default options, default "
             "device; each model's database fitted in one batch (time: extraction, upload and fit; the files "
             "read once beforehand).", "",
             "Score: rmse_log, the solid-angle weighted RMS of ln(1 + f cos theta_i) against the data's, over the "
             "cells inside the 80 degree cut-off (Löw et al.'s E2 with MERL's bin weights), one function for every "
             "fit; brdfcl's fits evaluated in float64. Published fits: SGD (Bagher et al. 2012), ABC "
             "microfacet and ABC smooth surface (Löw et al. 2012, E2 fits), parameters from BBM's fits/ "
             "(bench/published/, each file's header gives the source); they were fitted to measured MERL, not to "
             "these tables. Ratio: brdfcl's rmse_log over the published one's, per material.", "",
             "Against the better of the SGD and ABC microfacet fits (the default is measured against these two):", "",
             head, "|---|---|---|---|---|"]
    lines += _summary(specs, scores, seconds, ("sgd_bagher2012", "abc_low2012_microfacet_e2"))
    for s, chosen in run.get("models", {}).items():
        count: dict[str, int] = {}
        for m in chosen.values():
            count[m] = count.get(m, 0) + 1
        lines += ["", f"`{s}`: what `brdfcl fit-all` fits when no model is given, each material's reflection lobe "
                  f"in the form of least penalised error among {DEFAULT_FORMS} (brdfcl.optim.forms); chosen: "
                  + ", ".join(f"`{m}` {k}" for m, k in sorted(count.items())) + "."]
    lines += ["", "Against the best of all three published fits (ABC smooth surface too):", "", head,
              "|---|---|---|---|---|"]
    lines += _summary(specs, scores, seconds, PUBLISHED)
    lines += ["", "Per material (rmse_log; ratio: each brdfcl model over the better of SGD and ABC microfacet):", "",
              "| material | " + " | ".join(f"`{s}`" for s in specs) + " | "
              + " | ".join(SHORT[k] for k in PUBLISHED) + " | "
              + " | ".join(f"ratio {i + 1}" for i in range(len(specs))) + " |",
              "|---|" + "---|" * (2 * len(specs) + len(PUBLISHED))]
    for n in names:
        two = min((scores[n][k] for k in ("sgd_bagher2012", "abc_low2012_microfacet_e2") if k in scores[n]),
                  default=np.nan)
        cells_ = [f"{scores[n][k]:.4f}" for k in specs] + [f"{scores[n].get(k, np.nan):.4f}" for k in PUBLISHED]
        cells_ += [f"{scores[n][k] / two:.3f}" for k in specs]
        lines.append(f"| {n} | " + " | ".join(cells_) + " |")
    text = "\n".join(lines) + "\n"
    (out / "published.md").write_text(text)
    return text
