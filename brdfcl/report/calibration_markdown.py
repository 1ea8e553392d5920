"""calibration.md: a calibration study's summary (brdfcl.analysis.calibration_summary) as
Markdown tables, for a reader choosing or checking the diffraction tests' thresholds."""
from __future__ import annotations

import numpy as np

from brdfcl._words import count
from brdfcl.analysis import power
from brdfcl.analysis.analyze import MIN_DECIDABLE, RULE
from brdfcl.analysis.calibration_summary import FP_TARGET, LEGACY, Summary, detector, rule_text

LABELS = {"gradient": "gradient test", "wavelength": "wavelength law", "colour": "wavelength law, colour",
          "collapse": "curve collapse",
          "lobe": "lobe comparison", "verdict": "verdict"}
STATISTIC = {"gradient": f"score (>= {MIN_DECIDABLE} decidable cells)", "wavelength": "-ln(law ratio)",
             "colour": "-ln(law colour ratio)", "collapse": "-ln(collapse ratio)", "lobe": "lobe gain"}


def threshold_text(test, thresholds) -> str:
    """A test's threshold in the units a reader knows (a ratio for the two ratio tests)."""
    t = thresholds[test]
    if test in power.RATIOS:
        return f"ratio <= {np.exp(-t):.3g}"
    return f"{'score' if test == 'gradient' else 'gain'} >= {t:.3g}"


def pct(k, n):
    """A count of n as a percentage with the count: ``12% (3/25)``."""
    return f"{100 * k / n:.0f}% ({k}/{n})" if n else "-"


def share_text(x):
    """A smallest share detected, "never" where none was."""
    return "never" if not np.isfinite(x) else f"{x:.2f}"


def markdown(summary: Summary, fp=FP_TARGET, epochs=None, timing=None) -> str:
    """calibration.md's text: cases and run time, each test's threshold and false positives, the
    verdict rule and its stability, the smallest share detected, false positives per class,
    detection against the share, and what the round trip changes case by case."""
    by, kinds, res, thr, chosen = summary.by, summary.kinds, summary.result, summary.thresholds, summary.chosen
    columns, halo, null_classes = summary.columns, summary.halo, summary.null_classes
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
    for t in power.TESTS:
        L.append(f"| {LABELS[t]} | {STATISTIC[t]} | {threshold_text(t, thr)} | "
                 + " | ".join(pct(*res["fp"][t, k]) if k in kinds else "-" for k in ("original", "roundtrip")) + " |")
    L += ["", "## The verdict rule", "",
          f"* legacy (the rule before the law test): {rule_text(LEGACY)};",
          f"* calibrated: {rule_text(chosen)}: of the rules on a grid of round thresholds "
          f"(brdfcl.analysis.power.GRID), the one with the highest detection over the diffraction cases "
          f"(mean of the two table kinds) with <= {100 * fp:.0f}% false positives on each no-diffraction class "
          f"of each table kind, by the one-standard-error rule; false positives "
          f"{pct(*res['fp']['verdict:calibrated', 'original'])} original, "
          + (f"{pct(*res['fp']['verdict:calibrated', 'roundtrip'])} round trip" if "roundtrip" in kinds else "")
          + ";",
          f"* in the code (brdfcl.analysis.analyze.RULE): {rule_text(RULE)}"
          + (" (the calibrated rule)." if RULE == chosen else " (differs from the calibrated rule: update it)."),
          "", "Stability: chosen on half of the cases (split by name), counted on the other half:", ""]
    for rule, fps, hits in res["split"]:
        L.append(f"* {rule_text(rule)}: false positives "
                 + ", ".join(f"{k} {pct(*fps[k])}" for k in fps) + "; detected "
                 + ", ".join(f"{k} {pct(*hits[k])}" for k in hits))
    L.append("")
    L += ["## Smallest diffraction share detected 90% of the time", "",
          "| test | " + " | ".join(f"{k} (all)" for k in kinds)
          + (" | original, round-trip cases" if "roundtrip" in kinds else "")
          + " | " + " | ".join(f"{c} {k}" for c in halo for k in kinds) + " |",
          "| --- " * (1 + len(kinds) + ("roundtrip" in kinds) + len(halo) * len(kinds)) + "|"]
    for col in columns:
        cells = [share_text(res["smallest"][col, k]) for k in kinds]
        if "roundtrip" in kinds:
            cells.append(share_text(res["smallest"][col, "paired"]))
        cells += [share_text(res["smallest"][col, k, c]) for c in halo for k in kinds]
        L.append(f"| {col} | " + " | ".join(cells) + " |")
    L += ["", "## False positives per no-diffraction class", "",
          "| test | " + " | ".join(f"{c} {k}" for c in null_classes for k in kinds) + " |",
          "| --- " * (1 + len(null_classes) * len(kinds)) + "|"]
    for col in columns:
        L.append(f"| {col} | " + " | ".join(pct(*res["fp"][col, k, c]) for c in null_classes for k in kinds) + " |")
    L += ["", "## Detection rate against the diffraction share (all diffraction classes)", "",
          "| share | " + " | ".join(f"{col} {k}" for col in columns for k in kinds) + " |",
          "| --- " * (1 + len(columns) * len(kinds)) + "|"]
    shares = [s for s, _, _ in res["curves"][columns[0], kinds[0]]]
    for i, s in enumerate(shares):
        L.append(f"| {s:g} | " + " | ".join(pct(*res["curves"][col, k][i][1:]) for col in columns for k in kinds)
                 + " |")
    if "roundtrip" in kinds:
        L += ["", "## What the round trip changes, case by case (same cases, calibrated thresholds)", "",
              "| test | detected on both | only original | only round trip | neither |",
              "| --- | --- | --- | --- | --- |"]
        orig = {r["case"]: r for r in by["original"]}
        for col in columns:
            test, t, rule = detector(col, thr, {"legacy": LEGACY, "calibrated": chosen})
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
