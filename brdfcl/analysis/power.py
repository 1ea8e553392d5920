"""Power curves, false-positive rates and thresholds from calibration rows.

A row (brdfcl.analysis.calibration.analyse_cases) holds one synthetic case's true diffraction
``share`` and what each test measured.  Each test is read as a statistic that grows with the
evidence for diffraction, and detects where it reaches a threshold:

* ``gradient``: the score (share of decidable cells closer to grad f), where at least
  ``min_cells`` cells decide (else it detects nothing);
* ``wavelength``: ``-ln(law_ratio)`` (the wavelength law, brdfcl.analysis.law: the full model
  with each channel's wavelength fits the wide-angle region better than with one: law_ratio < 1 is
  a statistic > 0);
* ``colour``: ``-ln(law_colour_ratio)``, the same comparison on the colour alone (each channel's
  log residual minus the channels' mean), where a misfit the channels share cancels;
* ``collapse``: ``-ln(ratio)`` of the curve collapse (brdfcl.analysis.wavelength: the channels'
  binned curves collapse better against f_c than against f0), the law's picture, measured for
  comparison; no rule reads it;
* ``lobe``: the lobe gain, ln(best penalised error without diffraction / best with it);
* ``verdict``: a brdfcl.analysis.analyze.Rule applied to the row's statistics.

Thresholds are chosen on the no-diffraction rows only (``threshold_at``, ``test_threshold``): the
smallest one that leaves at most a given share of them detected, on the original and on the
round-tripped tables alike.  ``choose_rule`` picks the verdict's thresholds jointly on a grid of
round values: the combination with the highest detection over the diffraction rows whose
false-positive rate is at most the target on each no-diffraction class of each table kind;
``split_check`` chooses on half the cases and counts on the other half.
"""
from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np

from brdfcl.analysis.analyze import MIN_DECIDABLE, Rule

TESTS = ("gradient", "wavelength", "colour", "collapse", "lobe")
RATIOS = {"wavelength": "law_ratio", "colour": "law_colour_ratio", "collapse": "wl_ratio"}   # a row's ratio tests


def statistic(row, test, min_cells=MIN_DECIDABLE) -> float:
    """The test's statistic of one row (NaN where the test cannot decide)."""
    if test == "gradient":
        return float(row["grad_score"]) if int(row["grad_cells"]) >= min_cells else float("nan")
    if test in RATIOS:
        r = float(row.get(RATIOS[test], "nan"))
        return float(-np.log(r)) if r > 0 else (float("inf") if r == 0 else float("nan"))
    if test == "lobe":
        return float(row["lobe_gain"])
    raise ValueError(f"unknown test '{test}'; valid: {', '.join(TESTS)}")


def rule_margins(row, rule: Rule) -> dict:
    ratio = rule.wavelength_ratio(float(row["law_ratio"]), float(row["wl_ratio"]),
                                  float(row.get("law_colour_ratio", "nan")))
    return rule.margins(float(row["grad_score"]), int(row["grad_cells"]), ratio,
                        float(row["lobe_gain"]))


def detects(row, test, threshold=None, rule: Rule | None = None) -> bool:
    """Whether a test (or ``verdict`` under ``rule``) calls the row diffraction."""
    if test == "verdict":
        rule = rule or Rule()
        return bool(rule.diffraction(rule_margins(row, rule)))
    s = statistic(row, test)
    return bool(np.isfinite(s) and s >= threshold) or s == np.inf


def rate(rows, test, threshold=None, rule=None):
    """(detected, n) over rows."""
    hits = sum(detects(r, test, threshold, rule) for r in rows)
    return hits, len(rows)


def wilson(k, n, z=1.96):
    """95% Wilson interval of a binomial rate k/n."""
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(c - h, 0.0), min(c + h, 1.0)


def threshold_at(null_rows, test, fp=0.05):
    """The smallest threshold at which at most ``fp`` of the no-diffraction rows are detected
    (halfway between the null statistics on either side; above the largest if none may be)."""
    s = np.array([statistic(r, test) for r in null_rows])
    s = np.sort(s[np.isfinite(s)])[::-1]
    allowed = int(np.floor(fp * len(null_rows) + 1e-9))
    if allowed >= s.size:
        return float("-inf")
    hi = s[allowed - 1] if allowed > 0 else s[0] + max(abs(s[0]) * 0.01, 1e-3)
    return float(0.5 * (s[allowed] + hi)) if allowed > 0 else float(hi)


def power_curve(rows, test, threshold=None, rule=None, shares=None):
    """[(share, detected, n)] over the rows of each share."""
    shares = sorted({float(r["share"]) for r in rows}) if shares is None else shares
    out = []
    for s in shares:
        sel = [r for r in rows if abs(float(r["share"]) - s) < 1e-12]
        k, n = rate(sel, test, threshold, rule)
        out.append((s, k, n))
    return out


def smallest_share(curve, power=0.9):
    """The smallest share from which on the detection rate stays at least ``power`` (linear
    interpolation in log share between the grid points around the crossing); NaN if never."""
    pts = [(s, k / n) for s, k, n in curve if n > 0 and s > 0]
    if not pts or pts[-1][1] < power:
        return float("nan")
    i = len(pts) - 1
    while i > 0 and pts[i - 1][1] >= power:
        i -= 1
    if i == 0:
        return pts[0][0]
    (s0, p0), (s1, p1) = pts[i - 1], pts[i]
    t = (power - p0) / (p1 - p0)
    return float(np.exp(np.log(s0) + t * (np.log(s1) - np.log(s0))))


def test_threshold(rows, test, fp=0.05):
    """A test's threshold alone: the smallest at which at most ``fp`` of the no-diffraction rows of
    each table kind (original, round trip) are detected, i.e. the larger of the two."""
    nulls = [r for r in rows if float(r["share"]) == 0]
    kinds = sorted({r["table"] for r in nulls})
    return max(threshold_at([r for r in nulls if r["table"] == k], test, fp) for k in kinds)


GRID = {"gradient_score": (0.0, 0.1, 0.2, 0.3),
        "gradient_decisive": (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, float("inf")),
        "wavelength_decisive": (0.0, 0.9, 0.95, 0.97, 0.98, 0.99, 1.0),
        "wavelength_veto": (1.02, 1.05, 1.1, 1.25, 1.5, 2.0, float("inf")),
        "lobe_gain": (-0.1, -0.05, -0.025, 0.0, 0.025, 0.05, 0.1),
        "gradient_required": (False, True),
        "min_cells": (30, 100),
        "wavelength_test": ("law", "colour", "both")}
"""The verdict rules ``choose_rule`` tries: round thresholds, so that the choice cannot follow
single calibration cases (inf and 0: the test is never evidence, never contradicts), on the law's
ratio, on its colour ratio or on the larger of the two (Rule.wavelength_ratio)."""


def _kind_rates(rows, rule, kinds):
    return [rate([r for r in rows if r["table"] == k], "verdict", rule=rule) for k in kinds]


class _Columns:
    """Rows as arrays for Rule.margins, with each row's (table kind, class) group."""

    def __init__(self, rows):
        self.score = np.array([float(r["grad_score"]) for r in rows])
        self.cells = np.array([int(r["grad_cells"]) for r in rows])
        self.law = np.array([float(r["law_ratio"]) for r in rows])
        self.collapse = np.array([float(r["wl_ratio"]) for r in rows])
        self.colour = np.array([float(r.get("law_colour_ratio", "nan")) for r in rows])
        self.gain = np.array([float(r["lobe_gain"]) for r in rows])
        self.null = np.array([float(r["share"]) == 0 for r in rows])
        groups = sorted({(r["table"], r["class"]) for r in rows})
        self.group = np.array([groups.index((r["table"], r["class"])) for r in rows], dtype=int)
        self.kind = np.array([r["table"] for r in rows])
        self.kinds = sorted(set(self.kind))

    def detected(self, rule: Rule) -> np.ndarray:
        ratio = rule.wavelength_ratio(self.law, self.collapse, self.colour)
        return np.asarray(rule.diffraction(rule.margins(self.score, self.cells, ratio, self.gain)), dtype=bool)


def choose_rule(rows, fp=0.05, base: Rule | None = None, grid=None):
    """The verdict rule chosen on the calibration rows: (Rule, its detection rate).

    The rule keeps its form (the lobe comparison decides, the gradient test and the wavelength law
    may contradict, one of them must be evidence, the gradient test may be required to decide);
    only its settings move, over ``GRID``.  Admissible: a false-positive rate at most ``fp`` on the
    rows of each no-diffraction class of each table kind separately (a class of fewer than 1/fp
    cases may have none).  Detection: the mean over the table kinds of the rate over the
    diffraction rows.  Kept, by the one-standard-error rule of model selection: among the
    admissible rules whose detection is within one binomial standard error of the best, the one with
    the fewest false positives; then the higher detection; then the stricter thresholds."""
    base = base or Rule()
    grid = grid or GRID
    cols = _Columns(rows)
    null_groups = np.unique(cols.group[cols.null])
    sizes = np.bincount(cols.group[cols.null], minlength=cols.group.max() + 1)
    allowed = np.floor(fp * sizes + 1e-9)
    power_of = [(~cols.null) & (cols.kind == k) for k in cols.kinds]
    names = list(grid)
    scored = []
    for values in itertools.product(*(grid[k] for k in names)):
        rule = replace(base, **dict(zip(names, values)))
        hit = cols.detected(rule)
        fps = np.bincount(cols.group[cols.null & hit], minlength=sizes.size)
        if np.any(fps[null_groups] > allowed[null_groups]):
            continue
        rates = [float(hit[m].mean()) if m.any() else 0.0 for m in power_of]
        p = float(np.mean(rates))
        se = float(np.sqrt(sum(q * (1 - q) / max(int(m.sum()), 1) for q, m in zip(rates, power_of)))
                   / len(rates))
        strict = (rule.gradient_required, rule.gradient_score, -rule.gradient_decisive, rule.lobe_gain,
                  -rule.wavelength_decisive, -rule.wavelength_veto, rule.min_cells)
        scored.append((p, se, -int(fps.sum()), strict, rule))
    if not scored:
        return None, float("nan")
    best_p, best_se = max((x[0], x[1]) for x in scored)
    near = [x for x in scored if x[0] >= best_p - best_se]
    p, _, _, _, rule = max(near, key=lambda x: (x[2], x[0], x[3]))
    return rule, p


def split_check(rows, fp=0.05):
    """The choice's stability: choose on one half of the cases (by name), count false positives and
    detections on the other, both ways.  [(rule, {kind: (fp hits, n)}, {kind: (detected, n)})]."""
    import zlib

    half = {r["case"]: zlib.crc32(r["case"].encode()) % 2 for r in rows}
    kinds = sorted({r["table"] for r in rows})
    out = []
    for h in (0, 1):
        rule, _ = choose_rule([r for r in rows if half[r["case"]] == h], fp)
        other = [r for r in rows if half[r["case"]] != h]
        nulls = [r for r in other if float(r["share"]) == 0]
        pw = [r for r in other if float(r["share"]) > 0]
        out.append((rule, dict(zip(kinds, _kind_rates(nulls, rule, kinds))),
                    dict(zip(kinds, _kind_rates(pw, rule, kinds)))))
    return out
