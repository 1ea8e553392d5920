"""The numbers of a calibration study from its rows (brdfcl.analysis.calibration_store): each
test's threshold at the false-positive target, the verdict rule chosen on a grid, false-positive
rates, power curves and the smallest share detected, per table kind and per class.

The numbers come from brdfcl.analysis.power; this module reads the rows into numbers and lays
the results out by column (a test at its threshold, or a verdict rule), table kind and class, for
the Markdown (brdfcl.report.calibration_markdown) and the figures
(brdfcl.report.calibration_figures).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdfcl.analysis import power
from brdfcl.analysis.analyze import Rule

FP_TARGET = 0.05

LEGACY = Rule(gradient_score=0.2, gradient_decisive=0.2, min_cells=30, wavelength_decisive=0.0, wavelength_veto=5.0,
              lobe_gain=0.0, gradient_required=True, wavelength_test="collapse")
"""The rule before the wavelength law's model comparison (calibrated on the curve collapse: 0.2
gradient score where at least 30 cells must decide, a veto at a collapse ratio of 5), which
calibration.md compares with the one calibrated now."""
NUMERIC = ("share", "grad_score", "wl_ratio", "law_ratio", "law_colour_ratio", "law_error", "law_error_grey",
           "lobe_gain", "noise", "missing", "rmse_full", "rmse_no_diffraction", "rmse_grey")


def rule_text(rule: Rule) -> str:
    """A verdict rule in words."""
    g = (f">= {rule.min_cells} gradient cells decide and score >= {rule.gradient_score:g}" if rule.gradient_required
         else f"gradient score >= {rule.gradient_score:g} where >= {rule.min_cells} cells decide")
    w = {"collapse": "curve-collapse ratio", "colour": "law colour ratio",
         "both": "larger of the law ratio and its colour ratio"}.get(rule.wavelength_test, "law ratio")
    evidence = [f"gradient score >= {rule.gradient_decisive:g}"] if np.isfinite(rule.gradient_decisive) else []
    evidence += [f"{w} < {rule.wavelength_decisive:g}"] if rule.wavelength_decisive > 0 else []
    veto = f"{w} < {rule.wavelength_veto:g}" if np.isfinite(rule.wavelength_veto) else f"no {w} veto"
    return f"lobe gain > {rule.lobe_gain:g}, {g}, {veto}; evidence: {' or '.join(evidence) or 'none needed'}"


def numeric_rows(rows) -> list[dict]:
    """Rows as read from cases.csv (strings) with their statistics as numbers (NaN where empty)."""
    out = []
    for r in rows:
        r = dict(r)
        for k in NUMERIC:
            r[k] = float(r[k]) if r.get(k) not in ("", None) else float("nan")
        r["grad_cells"] = int(float(r["grad_cells"] or 0))
        out.append(r)
    return out


def detector(test, thresholds, rules):
    """(test name for power.rate, threshold, rule) of a column: a test at its threshold, or a verdict rule."""
    if test in thresholds:
        return test, thresholds[test], None
    return "verdict", None, rules[test.split(":")[1]]


@dataclass
class Summary:
    """A study's rows and what was computed from them."""
    rows: list            # numeric rows (numeric_rows)
    by: dict              # {table kind: its rows}
    kinds: list           # the table kinds present: "original", "roundtrip"
    thresholds: dict      # {test: threshold at the false-positive target}
    chosen: Rule          # the verdict rule chosen on power.GRID
    rules: dict           # {"legacy": LEGACY, "calibrated": chosen}
    columns: list         # power.TESTS, then "verdict:legacy", "verdict:calibrated"
    halo: list            # the diffraction classes present
    null_classes: list    # the no-diffraction classes present
    result: dict          # thresholds, rule, fp, smallest, curves, split (keyed by column, kind, class)


def summarise_rows(rows, fp=FP_TARGET) -> Summary:
    """Thresholds, the chosen rule, false-positive rates and power curves from a study's rows
    (strings as read from cases.csv, or numbers)."""
    rows = numeric_rows(rows)
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
    res: dict = {"thresholds": thr, "rule": chosen, "fp": {}, "smallest": {}, "curves": {}, "split": res_split}
    for col in columns:
        test, t, rule = detector(col, thr, rules)
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
    return Summary(rows, by, kinds, thr, chosen, rules, columns, halo, null_classes, res)
