#!/usr/bin/env python3
"""Which reflection-lobe forms a default would need: candidate forms of the three-lobe
model fitted to every proxy material, each material's form chosen by the lobe comparison's
penalised error (brdfcl.optim.selection), and the chosen fits scored against the published SGD
and ABC fits (bench/compare_published.py, same cells and metric).

Forms fitted (one batch each, default options): ``ggx`` (the default model), ``gtr`` (warm
started from the ggx fit with gamma = 2, `Fitter.fit(start=...)`), ``gtr-hc`` (height-correlated
Smith, warm started from the gtr fit), ``gtr-dielectric`` (its own global search: its Fresnel
has one index where Schlick has an F0 per channel), ``gtr-dielectric-warm`` (the same model
warm started from the gtr fit, `dielectric_from_schlick`), ``abc`` (Löw et al. 2012's NDF
with Schlick, its own global search) and ``abc-warm`` (the same, warm started from the
gtr-dielectric fit, `abc_from_gtr`).  Reported per set of candidates: the median
ratio to the better of SGD and ABC microfacet, the materials worse than it, the forms chosen, the
time of the fits it needs.  Writes bench/results/forms_published.md.

    python bench/bench_forms.py [--data DIR]
"""
from __future__ import annotations

import argparse
import datetime
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import compare_published as cp  # noqa: E402

from brdfcl import __version__  # noqa: E402
from brdfcl.data.merl import list_database, read_merl  # noqa: E402
from brdfcl.optim.fit import FitOptions, Fitter  # noqa: E402
from brdfcl.optim.forms import abc_from_gtr, dielectric_from_schlick, warm_start  # noqa: E402
from brdfcl.optim.selection import select  # noqa: E402

HERE = Path(__file__).resolve().parent


FORMS = {   # key: (model, the form it starts from (None: its own global search), how)
    "ggx": ("diffuse+diffraction+ggx", None, None),
    "gtr": ("diffuse+diffraction+gtr", "ggx", warm_start),
    "gtr-hc": ("diffuse+diffraction+gtr:smith-hc:schlick", "gtr", warm_start),
    "gtr-dielectric": ("diffuse+diffraction+gtr:smith:dielectric", None, None),
    "gtr-dielectric-warm": ("diffuse+diffraction+gtr:smith:dielectric", "gtr", dielectric_from_schlick),
    "abc": ("diffuse+diffraction+abc", None, None),
    "abc-warm": ("diffuse+diffraction+abc", "gtr-dielectric", abc_from_gtr)}
SETS = (("ggx",), ("gtr",), ("gtr-dielectric",), ("gtr-dielectric-warm",), ("abc",), ("ggx", "gtr"),
        ("gtr", "gtr-dielectric"), ("gtr", "gtr-dielectric-warm"), ("ggx", "gtr", "gtr-dielectric"),
        ("ggx", "gtr", "gtr-hc", "gtr-dielectric"), ("gtr-dielectric", "abc"), ("ggx", "gtr-dielectric-warm", "abc"),
        ("ggx", "gtr", "gtr-dielectric-warm", "abc"), ("abc-warm",), ("gtr-dielectric", "abc-warm"))
RIVALS = ("sgd_bagher2012", "abc_low2012_microfacet_e2")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=str(Path.home() / ".cache" / "brdfcl" / "proxy-all"))
    ap.add_argument("--out", default=str(HERE / "results" / "forms_published.md"))
    args = ap.parse_args(argv)
    paths = [Path(p) for p in list_database(args.data)]
    fitters = {k: Fitter(FitOptions(model=spec)) for k, (spec, _, _) in FORMS.items()}
    tables = [read_merl(p) for p in paths]
    loaded = fitters["ggx"].load(tables)
    names = loaded.names
    results, seconds = {}, {}
    for k, (_, warm, convert) in FORMS.items():
        t = time.perf_counter()
        start = convert(results[warm], fitters[k].model) if warm else None
        results[k] = fitters[k].fit_loaded(loaded, start=start)
        seconds[k] = time.perf_counter() - t
        print(f"{k}: {seconds[k]:.1f} s", flush=True)
    specs = {k: f.model.spec for k, f in fitters.items()}
    fits = {k: {r.name: (specs[k], np.array([r.params[n] for n in fitters[k].model.names])) for r in results[k]}
            for k in FORMS}
    scores = cp.score(tables, list(FORMS), fits)       # {material: {form key or published fit: rmse_log}}
    lines = [f"# Forms of the reflection lobe against the published fits ({datetime.date.today()})", "",
             f"Made by `python bench/bench_forms.py`. Data: MERL-proxy ({args.data}), {len(names)} materials. CPU: "
             f"{cp.cpu_name()}; brdfcl {__version__}; default device, default options. Forms: "
             + "; ".join(f"`{k}` = `{specs[k]}`" + (f" (warm start from `{w}`)" if w else " (global search)")
                         for k, (_, w, _) in FORMS.items()) + ".", "",
             "Each material's form is the candidate of least penalised error (rmse_log x (1 + 0.02 x free "
             "parameters), the lobe comparison's criterion); its fit is scored as in published.md and divided by "
             "the better of the SGD and ABC microfacet fits. Time: the fits the set needs, one batch each, single "
             "runs in one process (reading excluded).", "",
             "| candidates | median ratio | materials <= 0.7 | worse than SGD / ABC (ratio) | chosen | fit time (s) |",
             "|---|---|---|---|---|---|"]
    for combo in SETS:
        need = set(combo)
        for k in combo:                                    # a warm start needs its source fitted too
            while FORMS[k][1]:
                k = FORMS[k][1]
                need.add(k)
        ratios, worse, chosen = [], [], {}
        for i, n in enumerate(names):
            errs = {k: results[k][i].errors["rmse_log"] for k in combo}
            c, _ = select(errs, {k: specs[k] for k in combo})
            chosen[c] = chosen.get(c, 0) + 1
            r = scores[n][c] / min(scores[n][k] for k in RIVALS)
            ratios.append(r)
            if r > 1:
                worse.append(f"{n} ({r:.3f})")
        lines.append(f"| {', '.join(combo)} | {statistics.median(ratios):.3f} | {sum(r <= 0.7 for r in ratios)} | "
                     f"{len(worse)}{': ' + ', '.join(worse) if worse else ''} | "
                     f"{', '.join(f'{k} {v}' for k, v in sorted(chosen.items()))} | "
                     f"{sum(seconds[k] for k in need):.0f} |")
    text = "\n".join(lines) + "\n"
    Path(args.out).write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
