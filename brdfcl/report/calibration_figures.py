"""The figures of a calibration study (brdfcl.analysis.calibration_summary): detection rate
against the diffraction share per test (``power.png``), each test's statistic against the share
with its threshold (``statistics.png``), and the verdict under the legacy and calibrated rules
(``verdict.png``).  matplotlib is imported only when a figure is drawn."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from brdfcl.analysis import power
from brdfcl.analysis.calibration_summary import Summary
from brdfcl.report.calibration_markdown import LABELS, STATISTIC, pct, threshold_text


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


def write_figures(out: Path, summary: Summary) -> None:
    """power.png (detection against share per test), statistics.png (each statistic against the
    share, with its threshold) and verdict.png (the verdict under the legacy and calibrated rules)."""
    rows, by, kinds, res, thr, halo = (summary.rows, summary.by, summary.kinds, summary.result, summary.thresholds,
                                       summary.halo)
    plt = _pyplot()
    cols = list(power.TESTS) + ["verdict:calibrated"]
    fig, axs = plt.subplots(2, 3, figsize=(17, 9), constrained_layout=True)
    for ax in axs.ravel()[len(cols):]:
        ax.set_visible(False)
    for ax, col in zip(axs.ravel(), cols):
        fps = " / ".join(pct(*res["fp"][col, k]) for k in kinds)
        name = LABELS[col.split(":")[0]] + (" (calibrated rule)" if ":" in col else f", {threshold_text(col, thr)}")
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

    fig, axs = plt.subplots(1, len(power.TESTS), figsize=(5 * len(power.TESTS), 5), constrained_layout=True)
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
        ax.axhline(thr[t], color="k", ls="--", lw=1,
                   label=f"threshold ({threshold_text(t, thr)}, 5% false positives)")
        ax.set_xscale("log")
        ax.set_xticks([x0] + shares)
        ax.set_xticklabels(["none"] + [f"{s:g}" for s in shares], rotation=45)
        ax.minorticks_off()
        ax.set_xlabel("diffraction share (none: no-diffraction classes)")
        ax.set_ylabel(STATISTIC[t])
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
                      label=f"{'previous' if name == 'legacy' else name} rule, {k} "
                            f"(false positives {pct(*res['fp'][col, k])})")
    _axes(ax, "Verdict 'diffraction' against the diffraction share",
          [x[0] for x in res["curves"]["verdict:legacy", "original"]])
    ax.legend(loc="upper left", fontsize=9)
    fig.savefig(out / "verdict.png")
    plt.close(fig)
