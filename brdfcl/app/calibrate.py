"""`brdfcl calibrate --out DIR`: how much diffraction the tests see, and what the proxy hides.

The study (brdfcl.analysis.calibration for the cases, brdfcl.analysis.nbrdf for the round trip,
brdfcl.analysis.power for the numbers), in chunks of cases so that memory stays bounded:

1. draw the cases of a Plan, tabulate and "measure" each (noise, grazing noise, missing cells);
2. fit the compared variants and run the tests on every measured table (``original``);
3. send every ``roundtrip_every``-th case through the NBRDF recipe (train a 6-21-21-3 network per
   table, tabulate it as merl_proxy.py does) and analyse the round-tripped table (``roundtrip``);
4. append each analysed case to ``DIR/cases.csv`` (a rerun resumes from it), then summarise
   (``summarise``): thresholds at the false-positive target, power curves, figures
   (``power.png``, ``statistics.png``, ``verdict.png``) and ``DIR/calibration.md``.

Over 250 lines: the study, its summary and its figures are one job whose parts share their
row format and nothing else uses; the numbers come from brdfcl.analysis.power.
"""
from __future__ import annotations

import csv
import json
import os
import time
from pathlib import Path

import numpy as np

from brdfcl._words import count
from brdfcl.analysis import nbrdf, power
from brdfcl.analysis.analyze import RULE, Rule
from brdfcl.analysis.calibration import QUICK, Compared, Plan, analyse_cases, synthesize
from brdfcl.optim.fit import FitOptions

DEFAULT_EPOCHS = 20          # the recipe runs 100; bench/results/calibration/epochs.md compares
QUICK_EPOCHS = 2
FP_TARGET = 0.05
CHUNK = 12


def _read_rows(path):
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _append_rows(path, rows):
    if not rows:
        return
    new = not os.path.exists(path)
    with open(path, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        if new:
            w.writeheader()
        w.writerows(rows)


def study(out, plan: Plan | None = None, epochs: int = DEFAULT_EPOCHS, roundtrip: bool = True,
          fp: float = FP_TARGET, options: FitOptions | None = None, chunk: int = CHUNK, log=print):
    """Run (or resume) the study into ``out``; returns the summary (``summarise``)."""
    log = log or (lambda s: None)
    plan = plan or Plan()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "cases.csv"
    done = {(r["case"], r["table"]) for r in _read_rows(path)}
    cases = plan.cases()
    rt_names = {c.name for c in plan.roundtrip(cases)} if roundtrip else set()
    compared = None
    t_start = time.perf_counter()
    timing = {"synthesis": 0.0, "analysis original": 0.0, "nbrdf training": 0.0, "nbrdf tabulation": 0.0,
              "analysis roundtrip": 0.0}
    for s in range(0, len(cases), chunk):
        part = [c for c in cases[s:s + chunk] if (c.name, "original") not in done
                or (c.name in rt_names and (c.name, "roundtrip") not in done)]
        if not part:
            continue
        compared = compared or Compared(options)
        t = time.perf_counter()
        tables = {c.name: synthesize(c)[1] for c in part}
        timing["synthesis"] += time.perf_counter() - t
        todo = [c for c in part if (c.name, "original") not in done]
        t = time.perf_counter()
        rows = analyse_cases(todo, tables, compared, batch=chunk, tag="original")
        timing["analysis original"] += time.perf_counter() - t
        rt = [c for c in part if c.name in rt_names and (c.name, "roundtrip") not in done]
        if rt:
            t = time.perf_counter()
            tr = nbrdf.train([tables[c.name] for c in rt], nbrdf.TrainOptions(epochs=epochs, seed=plan.seed))
            timing["nbrdf training"] += time.perf_counter() - t
            t = time.perf_counter()
            rt_tables = {c.name: nbrdf.tabulate(w) for c, w in zip(rt, tr.weights)}
            timing["nbrdf tabulation"] += time.perf_counter() - t
            del tables
            t = time.perf_counter()
            rt_rows = analyse_cases(rt, rt_tables, compared, batch=chunk, tag="roundtrip")
            timing["analysis roundtrip"] += time.perf_counter() - t
            for r, lt, lv in zip(rt_rows, tr.loss[:, -1], tr.test_loss):
                r["nbrdf_train_loss"], r["nbrdf_test_loss"] = float(lt), float(lv)
            rows += rt_rows
        for r in rows:
            r.setdefault("nbrdf_train_loss", "")
            r.setdefault("nbrdf_test_loss", "")
        _append_rows(path, rows)
        log(f"cases {min(s + chunk, len(cases))}/{len(cases)} ({time.perf_counter() - t_start:.0f} s): "
            + ", ".join(f"{r['case']} {r['table'][:4]} {r['verdict']}" for r in rows))
    timing["total"] = time.perf_counter() - t_start
    timing = _add_timing(out / "timing.json", timing)
    rows = _read_rows(path)
    return summarise(out, rows, fp=fp, epochs=epochs, timing=timing, log=log)


def _add_timing(path, timing):
    """Seconds per stage, summed over the runs that made cases.csv (a resumed study adds up)."""
    old = json.loads(path.read_text()) if path.exists() else {}
    new = {k: old.get(k, 0.0) + v for k, v in timing.items()}
    path.write_text(json.dumps(new, indent=1))
    return new


# --- summary ------------------------------------------------------------------------------------
LEGACY = Rule(gradient_score=0.5, min_cells=30, wavelength_decisive=1.5, lobe_gain=0.0, gradient_required=False)


def rule_text(rule: Rule) -> str:
    g = (f">= {rule.min_cells} gradient cells decide and score >= {rule.gradient_score:g}" if rule.gradient_required
         else f"gradient score >= {rule.gradient_score:g} where >= {rule.min_cells} cells decide")
    return f"lobe gain > {rule.lobe_gain:g}, {g}, wavelength ratio < {rule.wavelength_decisive:g}"
"""The rule before the calibration (issue 16: 0.5 gradient score, 1.5 wavelength ratio, 2% per parameter)."""
LABELS = {"gradient": "gradient test", "wavelength": "wavelength check", "lobe": "lobe comparison",
          "verdict": "verdict"}
NUMERIC = ("share", "grad_score", "wl_ratio", "lobe_gain", "noise", "missing", "rmse_full", "rmse_no_diffraction")


def _num(rows):
    out = []
    for r in rows:
        r = dict(r)
        for k in NUMERIC:
            r[k] = float(r[k]) if r.get(k) not in ("", None) else float("nan")
        r["grad_cells"] = int(float(r["grad_cells"] or 0))
        out.append(r)
    return out


def _pct(k, n):
    return f"{100 * k / n:.0f}% ({k}/{n})" if n else "-"


def _share(x):
    return "never" if not np.isfinite(x) else f"{x:.2f}"


def _detector(test, thresholds, rules):
    """(test name for power.rate, threshold, rule) of a column: a test at its threshold, or a verdict rule."""
    if test in thresholds:
        return test, thresholds[test], None
    return "verdict", None, rules[test.split(":")[1]]


def summarise(out, rows, fp=FP_TARGET, epochs=None, timing=None, log=print) -> dict:
    """Thresholds, power curves, false-positive rates, figures and calibration.md from the rows."""
    out = Path(out)
    rows = _num(rows)
    if timing is None and (out / "timing.json").exists():
        timing = json.loads((out / "timing.json").read_text())
    kinds = [k for k in ("original", "roundtrip") if any(r["table"] == k for r in rows)]
    by = {k: [r for r in rows if r["table"] == k] for k in kinds}
    nulls = [r for r in rows if r["share"] == 0]
    thr = {t: power.test_threshold(rows, t, fp) for t in power.TESTS}
    chosen, _ = power.choose_rule(rows, fp)
    res_split = power.split_check(rows, fp)
    rules = {"legacy": LEGACY, "calibrated": chosen}
    columns = list(power.TESTS) + ["verdict:legacy", "verdict:calibrated"]
    halo = sorted({r["cls"] if "cls" in r else r["class"] for r in rows if r["share"] > 0})
    null_classes = sorted({r["class"] for r in nulls})
    res = {"thresholds": thr, "rule": chosen, "fp": {}, "smallest": {}, "curves": {}, "split": res_split,
           "markdown": str(out / "calibration.md")}
    for col in columns:
        test, t, rule = _detector(col, thr, rules)
        for k in kinds:
            nk = [r for r in by[k] if r["share"] == 0]
            res["fp"][col, k] = power.rate(nk, test, t, rule)
            for c in null_classes:
                res["fp"][col, k, c] = power.rate([r for r in nk if r["class"] == c], test, t, rule)
            pk = [r for r in by[k] if r["share"] > 0]
            res["curves"][col, k] = power.power_curve(pk, test, t, rule)
            res["smallest"][col, k] = power.smallest_share(res["curves"][col, k])
            for c in halo:
                cur = power.power_curve([r for r in pk if r["class"] == c], test, t, rule)
                res["curves"][col, k, c] = cur
                res["smallest"][col, k, c] = power.smallest_share(cur)
            if k == "original" and "roundtrip" in kinds:       # the original on the round trip's cases
                paired = {r["case"] for r in by["roundtrip"]}
                cur = power.power_curve([r for r in pk if r["case"] in paired], test, t, rule)
                res["curves"][col, "paired"] = cur
                res["smallest"][col, "paired"] = power.smallest_share(cur)
    _figures(out, rows, by, kinds, res, thr, rules, halo)
    (out / "calibration.md").write_text(_markdown(rows, by, kinds, res, thr, chosen, columns, halo, null_classes,
                                                  fp, epochs, timing))
    if log:
        log(f"calibration: thresholds {', '.join(f'{k} {v:.4g}' for k, v in thr.items())}; "
            f"verdict rule: {rule_text(chosen)}")
    return res


def _markdown(rows, by, kinds, res, thr, chosen, columns, halo, null_classes, fp, epochs, timing):
    L = ["# Calibration of the diffraction tests", ""]
    n_cases = {k: len(v) for k, v in by.items()}
    L += [f"Cases: {', '.join(f'{n} {k}' for k, n in n_cases.items())} (diffraction classes "
          f"{', '.join(halo)}; no-diffraction classes {', '.join(null_classes)}); NBRDF round trip "
          f"{count(epochs, 'epoch')}." if epochs else "", ""]
    if timing:
        L += ["Run time: " + ", ".join(f"{k} {v / 60:.1f} min" for k, v in timing.items() if v) + ".", ""]
    L += [f"## Each test alone at <= {100 * fp:.0f}% false positives (thresholds chosen on the no-diffraction "
          "cases, on the original and on the round-tripped tables alike)", "",
          "| test | statistic | threshold | false positives, original | false positives, round trip |",
          "| --- | --- | --- | --- | --- |"]
    stat = {"gradient": "score (>= 30 decidable cells)", "wavelength": "-ln(ratio)", "lobe": "lobe gain"}
    shown = {"gradient": f"score >= {thr['gradient']:.3g}", "lobe": f"gain >= {thr['lobe']:.3g}",
             "wavelength": f"ratio <= {np.exp(-thr['wavelength']):.3g}"}
    for t in power.TESTS:
        L.append(f"| {LABELS[t]} | {stat[t]} | {shown[t]} | "
                 + " | ".join(_pct(*res["fp"][t, k]) if k in kinds else "-" for k in ("original", "roundtrip")) + " |")
    L += ["", "## The verdict rule", "",
          f"* legacy: {rule_text(LEGACY)};",
          f"* calibrated: {rule_text(chosen)}: of the rules on a grid of round thresholds "
          f"(brdfcl.analysis.power.GRID), the one with the highest detection over the diffraction cases "
          f"(mean of the two table kinds) with <= {100 * fp:.0f}% false positives on each table kind's "
          f"no-diffraction cases; false positives {_pct(*res['fp']['verdict:calibrated', 'original'])} original, "
          + (f"{_pct(*res['fp']['verdict:calibrated', 'roundtrip'])} round trip" if "roundtrip" in kinds else "")
          + ";",
          f"* in the code (brdfcl.analysis.analyze.RULE): {rule_text(RULE)}"
          + (" (the calibrated rule)." if RULE == chosen else " (differs from the calibrated rule: update it)."),
          "", "Stability: chosen on half of the cases (split by name), counted on the other half:", ""]
    for rule, fps, hits in res["split"]:
        L.append(f"* {rule_text(rule)}: false positives "
                 + ", ".join(f"{k} {_pct(*fps[k])}" for k in fps) + "; detected "
                 + ", ".join(f"{k} {_pct(*hits[k])}" for k in hits))
    L.append("")
    L += ["## Smallest diffraction share detected 90% of the time", "",
          "| test | " + " | ".join(f"{k} (all)" for k in kinds)
          + (" | original, round-trip cases" if "roundtrip" in kinds else "")
          + " | " + " | ".join(f"{c} {k}" for c in halo for k in kinds) + " |",
          "| --- " * (1 + len(kinds) + ("roundtrip" in kinds) + len(halo) * len(kinds)) + "|"]
    for col in columns:
        cells = [_share(res["smallest"][col, k]) for k in kinds]
        if "roundtrip" in kinds:
            cells.append(_share(res["smallest"][col, "paired"]))
        cells += [_share(res["smallest"][col, k, c]) for c in halo for k in kinds]
        L.append(f"| {col} | " + " | ".join(cells) + " |")
    L += ["", "## False positives per no-diffraction class", "",
          "| test | " + " | ".join(f"{c} {k}" for c in null_classes for k in kinds) + " |",
          "| --- " * (1 + len(null_classes) * len(kinds)) + "|"]
    for col in columns:
        L.append(f"| {col} | " + " | ".join(_pct(*res["fp"][col, k, c]) for c in null_classes for k in kinds) + " |")
    L += ["", "## Detection rate against the diffraction share (all diffraction classes)", "",
          "| share | " + " | ".join(f"{col} {k}" for col in columns for k in kinds) + " |",
          "| --- " * (1 + len(columns) * len(kinds)) + "|"]
    shares = [s for s, _, _ in res["curves"][columns[0], kinds[0]]]
    for i, s in enumerate(shares):
        L.append(f"| {s:g} | " + " | ".join(_pct(*res["curves"][col, k][i][1:]) for col in columns for k in kinds)
                 + " |")
    if "roundtrip" in kinds:
        L += ["", "## What the round trip changes, case by case (same cases, calibrated thresholds)", "",
              "| test | detected on both | only original | only round trip | neither |",
              "| --- | --- | --- | --- | --- |"]
        orig = {r["case"]: r for r in by["original"]}
        for col in columns:
            test, t, rule = _detector(col, thr, {"legacy": LEGACY, "calibrated": chosen})
            cnt = np.zeros((2, 2), int)
            for r in by["roundtrip"]:
                if r["share"] > 0 and r["case"] in orig:
                    cnt[int(power.detects(orig[r["case"]], test, t, rule)), int(power.detects(r, test, t, rule))] += 1
            L.append(f"| {col} | {cnt[1, 1]} | {cnt[1, 0]} | {cnt[0, 1]} | {cnt[0, 0]} |")
        loss = [float(r["nbrdf_test_loss"]) for r in by["roundtrip"] if r.get("nbrdf_test_loss") not in ("", None)]
        if loss:
            L += ["", f"NBRDF held-out loss (mean |ln(1 + f cos)| error): median {np.median(loss):.4g}, "
                  f"range {min(loss):.4g} to {max(loss):.4g}."]
    L += ["", "Figures: power.png (detection against share per test), statistics.png (each statistic against the "
          "share, with its threshold), verdict.png (the verdict under the legacy and calibrated rules).", ""]
    return "\n".join(L)


def _band(ax, curve, **kw):
    s = np.array([c[0] for c in curve])
    k = np.array([c[1] for c in curve])
    n = np.array([max(c[2], 1) for c in curve])
    lo_hi = np.array([power.wilson(a, b) for a, b in zip(k, n)])
    line, = ax.plot(s, k / n, marker="o", ms=4, **kw)
    ax.fill_between(s, lo_hi[:, 0], lo_hi[:, 1], color=line.get_color(), alpha=0.1, lw=0)


def _axes(ax, title, shares=()):
    ax.set_xscale("log")
    if len(shares):
        ax.set_xticks(list(shares))
        ax.set_xticklabels([f"{x:g}" for x in shares])
        ax.minorticks_off()
    ax.set_ylim(-0.03, 1.03)
    ax.axhline(0.9, color="0.6", lw=0.8, ls=":")
    ax.set_xlabel("diffraction share of the wide-angle energy")
    ax.set_ylabel("detection rate")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


PSD_COLORS = {"halo-hp": "#1f77b4", "halo-abc": "#2ca02c", "halo-gauss": "#9467bd"}


def _figures(out, rows, by, kinds, res, thr, rules, halo):
    plt = _pyplot()
    cols = list(power.TESTS) + ["verdict:calibrated"]
    fig, axs = plt.subplots(2, 2, figsize=(12, 9), constrained_layout=True)
    for ax, col in zip(axs.ravel(), cols):
        fps = " / ".join(_pct(*res["fp"][col, k]) for k in kinds)
        shown = {"gradient": f"score >= {thr['gradient']:.3g}", "lobe": f"gain >= {thr['lobe']:.3g}",
                 "wavelength": f"ratio <= {np.exp(-thr['wavelength']):.3g}"}
        name = LABELS[col.split(":")[0]] + (" (calibrated rule)" if ":" in col else f", {shown[col]}")
        _axes(ax, f"{name}\nfalse positives {fps} ({' / '.join(kinds)})",
              [x[0] for x in res["curves"][col, "original"]])
        for c in halo:
            s = [x[0] for x in res["curves"][col, "original", c]]
            v = [x[1] / max(x[2], 1) for x in res["curves"][col, "original", c]]
            ax.plot(s, v, color=PSD_COLORS.get(c, "0.5"), lw=1, alpha=0.8, label=f"original, {c}")
        _band(ax, res["curves"][col, "original"], color="k", lw=2, label="original, all classes")
        if "roundtrip" in kinds:
            _band(ax, res["curves"][col, "roundtrip"], color="#d62728", lw=2, ls="--", label="NBRDF round trip, all")
        ax.legend(loc="upper left", fontsize=9)
    fig.suptitle("Detection rate against the diffraction share (95% Wilson bands; dotted: 90%)")
    fig.savefig(out / "power.png")
    plt.close(fig)

    fig, axs = plt.subplots(1, 3, figsize=(15, 5), constrained_layout=True)
    shares = sorted({r["share"] for r in rows if r["share"] > 0})
    x0 = shares[0] / 3 if shares else 0.01
    rng = np.random.default_rng(0)
    for ax, t in zip(axs, power.TESTS):
        for k, color in (("original", "#1f77b4"), ("roundtrip", "#d62728")):
            if k not in kinds:
                continue
            pts = [(r["share"] or x0, power.statistic(r, t)) for r in by[k]]
            xs = np.array([p[0] for p in pts]) * np.exp(rng.uniform(-0.12, 0.12, len(pts)))
            ys = np.array([p[1] for p in pts])
            ax.scatter(xs, np.clip(ys, -5, 5), s=12, alpha=0.6, color=color, label=k)
        shown = f"ratio {np.exp(-thr[t]):.3g}" if t == "wavelength" else f"{thr[t]:.3g}"
        ax.axhline(thr[t], color="k", ls="--", lw=1, label=f"threshold ({shown}, 5% false positives)")
        ax.set_xscale("log")
        ax.set_xticks([x0] + shares)
        ax.set_xticklabels(["none"] + [f"{s:g}" for s in shares], rotation=45)
        ax.minorticks_off()
        ax.set_xlabel("diffraction share (none: no-diffraction classes)")
        ax.set_ylabel({"gradient": "gradient score", "wavelength": "-ln(wavelength ratio)",
                       "lobe": "lobe gain ln(pen. without / with)"}[t])
        ax.set_title(LABELS[t])
        ax.grid(alpha=0.3)
        ax.legend(fontsize=9, loc="upper center")
    fig.suptitle("Each test's statistic against the true diffraction share (undecided cases left out)")
    fig.savefig(out / "statistics.png")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(8, 5.5), constrained_layout=True)
    for name, color in (("legacy", "#ff7f0e"), ("calibrated", "#1f77b4")):
        col = f"verdict:{name}"
        for k, ls in (("original", "-"), ("roundtrip", "--")):
            if k in kinds:
                _band(ax, res["curves"][col, k], color=color, ls=ls,
                      label=f"{name} rule, {k} (false positives {_pct(*res['fp'][col, k])})")
    _axes(ax, "Verdict 'diffraction' against the diffraction share",
          [x[0] for x in res["curves"]["verdict:legacy", "original"]])
    ax.legend(loc="upper left", fontsize=9)
    fig.savefig(out / "verdict.png")
    plt.close(fig)


def add_parser(subparsers):
    """The ``calibrate`` command on an argparse subparsers object."""
    p = subparsers.add_parser("calibrate", help="detection power and false positives of the diffraction tests "
                                                "on synthetic materials, before and after the NBRDF round trip",
                              description="Measure how well the diffraction tests of brdfcl analyze work: draw "
                                          "synthetic materials with and without a diffraction lobe (MERL-like "
                                          "noise and missing cells), analyse each as measured and, for some, "
                                          "after the NBRDF round trip (a small network trained on the table), "
                                          "and write the thresholds at the false-positive target, power curves "
                                          "and figures to OUT/calibration.md. Each analysed case is appended to "
                                          "OUT/cases.csv: a rerun resumes from it. --quick runs a handful of "
                                          "cases in minutes.",
                              epilog="examples:\n  brdfcl calibrate --quick --out out/calibration-quick\n"
                                     "  brdfcl calibrate --out out/calibration --no-roundtrip")
    p.add_argument("--out", required=True, help="output folder (cases.csv, figures, calibration.md); "
                                                "a rerun resumes the cases already in cases.csv")
    p.add_argument("--quick", action="store_true", help="a handful of cases and 2 training epochs (minutes)")
    p.add_argument("--no-roundtrip", action="store_true", help="skip the NBRDF round trip")
    p.add_argument("--epochs", type=int, default=None,
                   help=f"NBRDF training epochs (default {DEFAULT_EPOCHS}, {QUICK_EPOCHS} with --quick; "
                        "the recipe: 100)")
    p.add_argument("--fp", type=float, default=FP_TARGET, help="false-positive target (default %(default)s)")
    p.add_argument("--seed", type=int, default=Plan().seed, help="seed of the cases (default %(default)s)")
    p.add_argument("--device", default=None,
                   help="OpenCL device of the fits: an index or part of a name from brdfcl info (default: the one "
                        "it marks chosen)")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    plan = QUICK if args.quick else Plan()
    plan = Plan(**{**plan.__dict__, "seed": args.seed})
    epochs = args.epochs if args.epochs is not None else (QUICK_EPOCHS if args.quick else DEFAULT_EPOCHS)
    s = study(args.out, plan, epochs=epochs, roundtrip=not args.no_roundtrip, fp=args.fp,
              options=FitOptions(device=args.device))
    print(f"calibration: {s['markdown']}")
    return 0
