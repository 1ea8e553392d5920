#!/usr/bin/env python3
"""The calibration study of the diffraction tests, with its two checks; results in bench/results/calibration/.

    python bench/calibrate.py                  # the study (brdfcl.app.calibrate.study), resumable
    python bench/calibrate.py --summary-only   # summary, figures and table again from cases.csv
    python bench/calibrate.py --epochs-check   # NBRDF round trip at 10, 20, 30 and 100 epochs
    python bench/calibrate.py --proxies        # the 80 MERL-proxy materials: legacy and calibrated rules
    python bench/calibrate.py --quick          # a few cases into a scratch folder (minutes)

Each part writes its own files (cases.csv + calibration.md + power.png, statistics.png,
verdict.png; epochs.csv + epochs.md; proxies.csv + proxies.md) and states its run time.  Run the
study first: the other two parts read the thresholds from the code (brdfcl.analysis.analyze.RULE).
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from brdfcl._cache import cache_dir
from brdfcl.analysis import nbrdf, power
from brdfcl.analysis.analyze import RULE, analyze_material, margins_of
from brdfcl.analysis.calibration import QUICK, Compared, Plan, analyse_cases, measured_share, synthesize
from brdfcl.analysis.calibration_store import read_rows
from brdfcl.analysis.calibration_study import DEFAULT_EPOCHS, QUICK_EPOCHS
from brdfcl.analysis.calibration_summary import LEGACY, numeric_rows, rule_text
from brdfcl.app.calibrate import study, summarise
from brdfcl.data.merl import read_merl
from brdfcl.model.compose import Model

HERE = Path(__file__).resolve().parent
OUT = HERE / "results" / "calibration"
PROXY_DIR = cache_dir() / "proxy-all"
BASELINE = Path(os.environ.get("BRDFCL_BASELINE", "/work/cmp/before/analyze/analysis.csv"))

# MERL material classes, for reading the proxy table only (no threshold is chosen on them)
MERL_CLASSES = {
    "metal": "alum-bronze aluminium black-oxidized-steel brass chrome grease-covered-steel nickel steel "
             "tungsten-carbide two-layer-gold",
    "metallic / effect paint": "blue-metallic-paint gold-metallic-paint gold-metallic-paint3 green-metallic-paint "
                               "green-metallic-paint2 red-metallic-paint silver-metallic-paint "
                               "color-changing-paint1 color-changing-paint3",
    "paint": "dark-blue-paint gold-paint light-red-paint orange-paint purple-paint silver-paint white-paint "
             "yellow-paint",
    "phenolic": "black-phenolic red-phenolic yellow-phenolic specular-black-phenolic specular-blue-phenolic "
                "specular-green-phenolic specular-orange-phenolic specular-red-phenolic "
                "specular-white-phenolic specular-yellow-phenolic",
    "plastic": "black-soft-plastic blue-acrylic gray-plastic green-acrylic maroon-plastic nylon pink-plastic pvc "
               "red-plastic red-specular-plastic teflon violet-acrylic white-acrylic yellow-matte-plastic "
               "yellow-plastic polyurethane-foam",
    "fabric": "beige-fabric black-fabric blue-fabric dark-specular-fabric green-fabric light-brown-fabric "
              "pink-fabric pink-fabric2 red-fabric white-fabric white-fabric2",
    "wood": "cherry-235 colonial-maple-223 ipswich-pine-221 natural-209 pickled-oak-260 special-walnut-224",
    "rubber": "blue-rubber green-latex neoprene-rubber pure-rubber violet-rubber white-diffuse-bball",
    "mineral / ceramic": "alumina-oxide aventurnine silicon-nitrade white-marble",
}
CLASS_OF = {m: c for c, names in MERL_CLASSES.items() for m in names.split()}


def log(s):
    print(s, flush=True)


def write_csv(path, rows):
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, restval="")
        w.writeheader()
        w.writerows(rows)


def epochs_check(out, epochs=(10, 20, 30, 100)):
    """Twelve round-trip cases trained to 100 epochs (the recipe), tabulated after 10, 20, 30 and 100."""
    t0 = time.perf_counter()
    plan = Plan()
    cases = plan.roundtrip(plan.cases())

    def first(cls, share=0.0, k=0):
        return [c for c in cases if c.cls == cls and c.share == share][k]
    pick = [first("halo-hp", s) for s in (0.2, 0.35, 0.5, 0.7, 0.9)] + [first("halo-abc", 0.5)]
    pick += [first("metal-ggx"), first("rough-metal"), first("rough-metal", k=1), first("layered"),
             first("layered", k=1), first("plastic")]
    tables = {c.name: synthesize(c)[1] for c in pick}
    compared = Compared()
    rows = analyse_cases(pick, tables, compared, tag="original", log=log)
    tr = nbrdf.train([tables[c.name] for c in pick], nbrdf.TrainOptions(epochs=max(epochs), seed=plan.seed),
                     log=log, snapshots=epochs)
    t_train = tr.seconds
    for e in epochs:
        rt = {c.name: nbrdf.tabulate(w) for c, w in zip(pick, tr.snapshots[e])}
        got = analyse_cases(pick, rt, compared, tag=f"epochs {e}", log=log)
        for r, i in zip(got, range(len(pick))):
            r["train_loss"] = float(tr.loss[i, e - 1])
        rows += got
    write_csv(out / "epochs.csv", rows)
    (out / "epochs.json").write_text(json.dumps({"epochs": list(epochs), "training_s": t_train,
                                                 "total_s": time.perf_counter() - t0}))
    epochs_markdown(out)


def epochs_markdown(out):
    """epochs.md from epochs.csv: each case's statistics per table, and detections at each test's
    calibrated threshold (cases.csv) and under the code's rule."""
    rows = numeric_rows(read_rows(out / "epochs.csv"))
    info = json.loads((out / "epochs.json").read_text())
    epochs = info["epochs"]
    names = list(dict.fromkeys(r["case"] for r in rows))
    L = ["# NBRDF round trip: fewer epochs against the recipe's 100", "",
         f"{len(names)} calibration cases (halo-hp at shares 0.2 to 0.9, halo-abc at 0.5, six without "
         f"diffraction), trained together for {max(epochs)} epochs ({info['training_s'] / 60:.1f} min), tabulated "
         f"after {', '.join(map(str, epochs))} epochs; total {info['total_s'] / 60:.1f} min. Verdicts under the "
         f"code's rule (brdfcl.analysis.analyze.RULE).", "",
         "| case | table | training loss | gradient score (cells) | law ratio | collapse ratio | lobe gain | verdict |",
         "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for name in names:
        for r in rows:
            if r["case"] == name:
                v = RULE.verdict(power.rule_margins(r, RULE))
                loss = float(r["train_loss"]) if r.get("train_loss") not in ("", None) else float("nan")
                L.append(f"| {name} | {r['table']} | {_fmt(loss, '.4g')} | {_fmt(r['grad_score'])} "
                         f"({r['grad_cells']}) | {_fmt(r['law_ratio'], '.4f')} | {_fmt(r['wl_ratio'])} | "
                         f"{_fmt(r['lobe_gain'], '+.3f')} | {v} |")
    cal_rows = read_rows(out / "cases.csv")
    if cal_rows:
        thr = {t: power.test_threshold(numeric_rows(cal_rows), t) for t in power.TESTS}
        L += ["", "Detections of the diffraction cases and false positives of the others, at each test's "
              "threshold of calibration.md and under the code's rule:", "",
              "| table | " + " | ".join(power.TESTS) + " | verdict | mean abs. change of the gradient score "
              f"against {max(epochs)} epochs |", "| --- " * (len(power.TESTS) + 3) + "|"]
        ref = {r["case"]: r for r in rows if r["table"] == f"epochs {max(epochs)}"}
        for table in ["original"] + [f"epochs {e}" for e in epochs]:
            sel = [r for r in rows if r["table"] == table]
            cells = []
            for t in list(power.TESTS) + ["verdict"]:
                d = [power.detects(r, t, thr.get(t), RULE) for r in sel if r["share"] > 0]
                f = [power.detects(r, t, thr.get(t), RULE) for r in sel if r["share"] == 0]
                cells.append(f"{sum(d)}/{len(d)} detected, {sum(f)}/{len(f)} false")
            dg = [abs(r["grad_score"] - ref[r["case"]]["grad_score"]) for r in sel
                  if np.isfinite(r["grad_score"]) and np.isfinite(ref[r["case"]]["grad_score"])]
            L.append(f"| {table} | " + " | ".join(cells) + f" | {np.mean(dg):.3f} |")
    (out / "epochs.md").write_text("\n".join(L) + "\n")
    log(f"epochs check: {out / 'epochs.md'}")


def _fmt(x, spec=".3g"):
    return "" if x is None or not np.isfinite(x) else format(x, spec)


def proxies(out, batch=10):
    """Every proxy material analysed once; verdicts under the legacy rule and the code's (calibrated)
    rule from the same fits, and the baseline verdicts of the run before (BASELINE)."""
    t0 = time.perf_counter()
    paths = sorted(PROXY_DIR.glob("*.binary"))
    if not paths:
        sys.exit(f"no proxy tables in {PROXY_DIR}")
    base = {r["material"]: r for r in csv.DictReader(open(BASELINE))} if BASELINE.exists() else {}
    compared = Compared()
    rows = []
    for s in range(0, len(paths), batch):
        tables = [read_merl(p) for p in paths[s:s + batch]]
        fits = compared.fit(tables)
        for t in tables:
            a = analyze_material(t.name, t.brdf(), {k: fits[k][t.name] for k in fits}, dict(compared.specs))
            m_new, m_old = margins_of(a), margins_of(a, LEGACY)
            b = base.get(t.name, {})
            rows.append({"material": t.name, "class": CLASS_OF.get(t.name, "other"),
                         "baseline_verdict": b.get("verdict", ""), "legacy_verdict": LEGACY.verdict(m_old),
                         "verdict": a.verdict, "verdict_by": RULE.binding(m_new),
                         "grad_score": a.gradient.mean_score, "grad_cells": int(a.gradient.n_cells.sum()),
                         "wl_ratio": a.wavelength.ratio, "law_ratio": a.law_ratio,
                         "law_colour_ratio": a.law.colour_ratio,
                         "lobe_gain": m_new["lobe"] + RULE.lobe_gain,
                         **{f"margin_{k}": v for k, v in m_new.items()},
                         "fitted_share": fitted_share(a),
                         "rmse_log_full": a.fits["full"].errors["rmse_log"],
                         "baseline_rmse_log_full": float(b.get("rmse_log_full") or "nan")})
        log(f"proxies {min(s + batch, len(paths))}/{len(paths)} ({time.perf_counter() - t0:.0f} s)")
    write_csv(out / "proxies.csv", rows)
    (out / "proxies.json").write_text(json.dumps({"seconds": time.perf_counter() - t0}))
    proxies_markdown(out)


def fitted_share(a):
    """The diffraction share of the wide-angle energy (as the calibration cases define it) in the
    material's full fit."""
    model = Model(a.specs["full"])
    return measured_share(model, model.only_lobes(a.fits["full"].params, None))


def why(r, rule, name):
    """The conditions of ``rule`` a proxy row fails (empty: it passes)."""
    m = power.rule_margins(r, rule)
    out = []
    if not m["lobe"] > 0:
        out.append(f"lobe gain {r['lobe_gain']:+.3f} <= {rule.lobe_gain:g}")
    if m["gradient"] < 0:
        out.append(f"gradient {r['grad_score']:.2f} < {rule.gradient_score:g}")
    elif rule.gradient_required and not np.isfinite(m["gradient"]):
        out.append(f"gradient undecided ({r['grad_cells']} cells)")
    ratio = rule.wavelength_ratio(r["law_ratio"], r["wl_ratio"], r.get("law_colour_ratio", float("nan")))
    if m["wavelength"] <= 0:
        out.append(f"{rule.wavelength_test} ratio {ratio:.3f} >= {rule.wavelength_veto:g}")
    if not m["evidence"] >= 0:
        short = []
        if np.isfinite(rule.gradient_decisive):
            decided = r["grad_cells"] >= rule.min_cells
            short.append(f"gradient {r['grad_score']:.2f} < {rule.gradient_decisive:g}" if decided
                         else f"gradient undecided ({r['grad_cells']} cells)")
        if rule.wavelength_decisive > 0:
            short.append(f"{rule.wavelength_test} ratio {ratio:.3f} >= {rule.wavelength_decisive:g}")
        out.append(f"no evidence ({', '.join(short)})")
    return f"{name}: " + (", ".join(out) if out else "passes")


def proxies_markdown(out, small=0.05):
    """proxies.md from proxies.csv: the table class by class, the verdicts that change and why, and
    how many verdicts hang on a small margin."""
    rows = read_rows(out / "proxies.csv")
    for r in rows:
        for k in ("grad_score", "wl_ratio", "law_ratio", "law_colour_ratio", "lobe_gain", "margin_gradient",
                  "margin_wavelength", "margin_lobe", "margin_evidence", "fitted_share"):
            r[k] = float(r[k]) if r.get(k) not in ("", None) else float("nan")
        r["grad_cells"] = int(r["grad_cells"])
        r["share"] = float("nan")
    info = json.loads((out / "proxies.json").read_text()) if (out / "proxies.json").exists() else {}
    L = ["# The 80 MERL-proxy materials under the calibrated rule", "",
         f"Calibrated rule (brdfcl.analysis.analyze.RULE): {rule_text(RULE)}; legacy: {rule_text(LEGACY)}. "
         f"Both verdicts from the same fits (this run); baseline: the verdicts of the run before ({BASELINE}). "
         f"Classes are for reading only: no threshold was chosen on them."
         + (f" Run time {info['seconds'] / 60:.1f} min." if info else ""), "",
         "| class | materials | diffraction (baseline) | diffraction (legacy rule, this run) | "
         "diffraction (calibrated) |", "| --- | --- | --- | --- | --- |"]
    for c in list(MERL_CLASSES) + ["other"]:
        sel = [r for r in rows if r["class"] == c]
        if sel:
            def names(key, sel=sel):
                d = [r["material"] for r in sel if r[key] == "diffraction"]
                return f"{len(d)}" + (f": {', '.join(d)}" if d else "")
            L.append(f"| {c} | {len(sel)} | {names('baseline_verdict')} | {names('legacy_verdict')} | "
                     f"{names('verdict')} |")
    n = {k: sum(r[k] == "diffraction" for r in rows) for k in ("baseline_verdict", "legacy_verdict", "verdict")}
    L.append(f"| all | {len(rows)} | {n['baseline_verdict']} | {n['legacy_verdict']} | {n['verdict']} |")
    changed = [r for r in rows if r["verdict"] != (r["baseline_verdict"] or r["legacy_verdict"])]
    L += ["", f"## Verdicts that change ({len(changed)}) and why", "",
          "| material | class | baseline | calibrated | why | least margin | gradient score (cells) | "
          "law ratio | collapse ratio | lobe gain | fitted share |", "| --- " * 11 + "|"]
    for r in changed:
        L.append(f"| {r['material']} | {r['class']} | {r['baseline_verdict']} | {r['verdict']} | "
                 f"{why(r, LEGACY, 'legacy')}; {why(r, RULE, 'calibrated')} | {r['verdict_by']} | "
                 f"{_fmt(r['grad_score'])} ({r['grad_cells']}) | {_fmt(r['law_ratio'], '.4f')} | "
                 f"{_fmt(r['wl_ratio'])} | {_fmt(r['lobe_gain'], '+.3f')} | {_fmt(r['fitted_share'], '.2f')} |")
    metals = [r for r in rows if r["class"] == "metal"]
    L += ["", "The metals, with the diffraction share of the wide-angle energy in their full fits (the calibration's "
          "measure; a fit's share is not the material's, but it says where the halo the tests look for would sit "
          "on the power curves):", "",
          "| metal | calibrated verdict | fitted share | gradient score (cells) | law ratio | collapse ratio | "
          "lobe gain |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in metals:
        L.append(f"| {r['material']} | {r['verdict']} | {_fmt(r['fitted_share'], '.2f')} | {_fmt(r['grad_score'])} "
                 f"({r['grad_cells']}) | {_fmt(r['law_ratio'], '.4f')} | {_fmt(r['wl_ratio'])} | "
                 f"{_fmt(r['lobe_gain'], '+.3f')} |")
    diff = [r for r in rows if r["verdict"] == "diffraction"]
    keys = ("lobe", "gradient", "wavelength", "evidence")

    def least(r):
        m = {k: r[f"margin_{k}"] for k in keys if np.isfinite(r[f"margin_{k}"])}
        return min(m.items(), key=lambda kv: kv[1])

    thin = [r for r in diff if least(r)[1] < small]
    L += ["", f"Of the {len(diff)} `diffraction` verdicts, {len(thin)} hang on a margin below {small:g} (lobe: gain - "
          f"{RULE.lobe_gain:g}; gradient: score - {RULE.gradient_score:g}; wavelength: ln({RULE.wavelength_veto:g} / "
          f"ratio); evidence: the larger of score - {RULE.gradient_decisive:g} and "
          f"ln({RULE.wavelength_decisive:g} / ratio))"
          + (": " + ", ".join(f"{r['material']} ({least(r)[0]} {least(r)[1]:+.3f})" for r in thin) if thin else "")
          + "."]
    same_fit = [r for r in rows if r["baseline_verdict"] and r["legacy_verdict"] != r["baseline_verdict"]]
    L += ["", f"Legacy rule on this run's fits against the baseline: {len(same_fit)} verdicts differ"
          + (f" ({', '.join(r['material'] for r in same_fit)})" if same_fit else "") + "."]
    (out / "proxies.md").write_text("\n".join(L) + "\n")
    log(f"proxies: {out / 'proxies.md'}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=None, help=f"output folder (default {OUT}; --quick: a scratch folder)")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--summary-only", action="store_true")
    ap.add_argument("--epochs-check", action="store_true")
    ap.add_argument("--epochs-summary", action="store_true", help="epochs.md again from epochs.csv")
    ap.add_argument("--proxies", action="store_true")
    ap.add_argument("--proxies-summary", action="store_true", help="proxies.md again from proxies.csv")
    ap.add_argument("--epochs", type=int, default=None)
    args = ap.parse_args(argv)
    out = Path(args.out or (Path("/tmp/brdfcl-calibrate-quick") if args.quick else OUT))
    out.mkdir(parents=True, exist_ok=True)
    if args.epochs_check:
        return epochs_check(out)
    if args.epochs_summary:
        return epochs_markdown(out)
    if args.proxies:
        return proxies(out)
    if args.proxies_summary:
        return proxies_markdown(out)
    epochs = args.epochs or (QUICK_EPOCHS if args.quick else DEFAULT_EPOCHS)
    if args.summary_only:
        summarise(out, read_rows(out / "cases.csv"), epochs=epochs, log=log)
        return 0
    study(out, QUICK if args.quick else Plan(), epochs=epochs, log=log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
