"""brdfcl's fits against the published fits of the field, side by side on the same tables.

Every material of the set is fitted by brdfcl (one batch per model, default options, the whole
fit timed), and every fit, brdfcl's and the published ones of `published.py` (SGD, Bagher et al.
2012; ABC microfacet and smooth surface, E2 fits, and Ashikhmin-Shirley and Cook-Torrance, E1 and E2
fits, Löw et al. 2012; seven models of Ngan et al. 2005, 86 materials), is scored by one function on
the same cells: ``rmse_log`` of brdfcl.model.metrics.errors, the solid-angle weighted RMS of
ln(1 + f cos theta_i) - ln(1 + f_measured cos theta_i) over every cell with theta_i, theta_o
(and the fit's cut-off) below 80 degrees, the E2 metric of Löw et al. with MERL's bin weights.
brdfcl's fits are evaluated by its float64 kernels (equal to the float64 reference to ~1e-15)
and scored by the same host function as the published ones.

Reported per material: each score, the ratio of brdfcl's to the better of SGD and ABC microfacet,
and the ratio to the best of all published fits of that material, naming that fit; the median
ratios, the materials where brdfcl is worse, how often each published model is the best, and the
time of each whole-database fit.  The published fits were made on measured MERL; on
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

PUBLISHED = tuple(published.MODELS)
"""Every published fit, scored where it has the material."""
TWO = ("sgd_bagher2012", "abc_low2012_microfacet_e2")
"""The pair the default is measured against first (the better of the two per material)."""
SHORT = {"sgd_bagher2012": "SGD", "abc_low2012_microfacet_e2": "ABC-mf", "abc_low2012_smooth_e2": "ABC-sm",
         "ashikhminshirley_low2012_e1": "AS-Low-E1", "ashikhminshirley_low2012_e2": "AS-Low-E2",
         "cooktorrance_low2012_e1": "CT-Low-E1", "cooktorrance_low2012_e2": "CT-Low-E2",
         "ashikhminshirley_ngan2005": "AS-Ngan", "blinnphong_ngan2005": "BlinnPhong-Ngan",
         "cooktorrance_ngan2005": "CT-Ngan", "he_ngan2005": "He-Ngan", "lafortune_ngan2005": "Lafortune-Ngan",
         "ward_ngan2005": "Ward-Ngan", "wardduer_ngan2005": "WardDuer-Ngan"}
assert set(SHORT) == set(PUBLISHED)


def best_published(row: dict[str, float], rivals: tuple[str, ...] = PUBLISHED) -> tuple[str | None, float]:
    """The published fit of least rmse_log among ``rivals`` in one material's scores, and its score
    (None, nan where the material has none of them)."""
    have = [k for k in rivals if k in row]
    if not have:
        return None, float("nan")
    k = min(have, key=lambda k: row[k])
    return k, row[k]


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
    best = {n: best_published(scores[n], rivals)[1] for n in names}
    rows = []
    for s in specs:
        ratio = np.array([scores[n][s] / best[n] for n in names])
        worse = [f"{n} ({r:.2f})" for n, r in zip(names, ratio) if r > 1]
        rows.append(f"| `{s}` | {seconds[s]:.1f} | {np.median(ratio):.3f} | {np.mean(ratio <= 0.7):.0%} | "
                    f"{len(worse)} of {len(names)}{': ' + ', '.join(worse) if worse else ''} |")
    return rows


def report(out: Path) -> str:
    """published.md and published.csv from published.json (``--published --report-only``).  A run made
    with fewer published models reports those it scored."""
    run = json.loads((out / "published.json").read_text())
    specs, scores, seconds = run["specs"], run["scores"], run["seconds"]
    names = sorted(scores)
    rivals = tuple(k for k in PUBLISHED if any(k in scores[n] for n in names))
    best = {n: best_published(scores[n], rivals) for n in names}
    two = {n: best_published(scores[n], TWO)[1] for n in names}
    with open(out / "published.csv", "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["material", *specs, *rivals, "best_published", "best_published_rmse_log",
                     *(f"ratio_{s}_to_best" for s in specs), *(f"ratio_{s}_to_sgd_abc" for s in specs)])
        for n in names:
            wr.writerow([n] + [f"{scores[n].get(k, np.nan):.6g}" for k in (*specs, *rivals)]
                        + [best[n][0] or "", f"{best[n][1]:.6g}"]
                        + [f"{scores[n][s] / best[n][1]:.6g}" for s in specs]
                        + [f"{scores[n][s] / two[n]:.6g}" for s in specs])
    head = ("| brdfcl model | whole-database fit (s) | median ratio | materials with ratio <= 0.7 | "
            "materials where brdfcl is worse (ratio) |")
    lines = [f"# brdfcl against the published fits ({run['date']})", "",
             f"Made by `python bench/bench_fit.py --published` (bench/compare_published.py). Data: {run['data']}, "
             f"{len(names)} materials. CPU: {run['cpu']}; brdfcl {run['version']}, default options, default "
             "device; each model's database fitted in one batch (time: extraction, upload and fit; the files "
             "read once beforehand).", "",
             "Score: rmse_log, the solid-angle weighted RMS of ln(1 + f cos theta_i) against the data's, over the "
             "cells inside the 80 degree cut-off (Löw et al.'s E2 with MERL's bin weights), one function for every "
             "fit; brdfcl's fits evaluated in float64. Published fits (" + ", ".join(SHORT[k] for k in rivals)
             + "): SGD (Bagher et al. 2012); ABC microfacet and smooth surface (E2), Ashikhmin-Shirley and "
             "Cook-Torrance (E1, E2) of Löw et al. 2012; Ngan et al. 2005 (86 of MERL's materials); parameters "
             "from BBM's fits/ (bench/published/, each file's header gives the source); they were fitted to "
             "measured MERL, not to these tables. Ratio: brdfcl's rmse_log over the published one's, per "
             "material.", "",
             "Against the better of the SGD and ABC microfacet fits (the default is measured against these two):", "",
             head, "|---|---|---|---|---|"]
    lines += _summary(specs, scores, seconds, TWO)
    for s, chosen in run.get("models", {}).items():
        count: dict[str, int] = {}
        for m in chosen.values():
            count[m] = count.get(m, 0) + 1
        lines += ["", f"`{s}`: what `brdfcl fit-all` fits when no model is given, each material's reflection lobe "
                  f"in the form of least penalised error among {DEFAULT_FORMS} (brdfcl.optim.forms); chosen: "
                  + ", ".join(f"`{m}` {k}" for m, k in sorted(count.items())) + "."]
    wins: dict[str, int] = {}
    for k, _ in best.values():
        if k:
            wins[k] = wins.get(k, 0) + 1
    lines += ["", f"Against the best of all {len(rivals)} published fits of each material (whichever it is):", "",
              head, "|---|---|---|---|---|"]
    lines += _summary(specs, scores, seconds, rivals)
    lines += ["", "The best published fit, materials: "
              + ", ".join(f"{SHORT[k]} {c}" for k, c in sorted(wins.items(), key=lambda kc: (-kc[1], kc[0])))
              + ". Every score is in published.csv.", "",
              "Per material (rmse_log; ratio to 2: each brdfcl model over the better of SGD and ABC microfacet; "
              "ratio to best: over the best published fit, named):", "",
              "| material | " + " | ".join(f"`{s}`" for s in specs) + " | " + " | ".join(SHORT[k] for k in TWO)
              + " | best published | its rmse_log | "
              + " | ".join(f"ratio {i + 1} to 2" for i in range(len(specs))) + " | "
              + " | ".join(f"ratio {i + 1} to best" for i in range(len(specs))) + " |",
              "|---|" + "---|" * (3 * len(specs) + len(TWO) + 2)]
    for n in names:
        k, b = best[n]
        cells_ = [f"{scores[n][s]:.4f}" for s in specs] + [f"{scores[n].get(t, np.nan):.4f}" for t in TWO]
        cells_ += [SHORT[k] if k else "-", f"{b:.4f}"]
        cells_ += [f"{scores[n][s] / two[n]:.3f}" for s in specs] + [f"{scores[n][s] / b:.3f}" for s in specs]
        lines.append(f"| {n} | " + " | ".join(cells_) + " |")
    text = "\n".join(lines) + "\n"
    (out / "published.md").write_text(text)
    return text
