"""The analysis figures of one material: the gradient test, the wavelength check and the fitted
components, each drawn in the shared style (brdfcl.report.style) and saved atomically.

brdfcl.report.writers.analysis_figures decides where and when they are written.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from brdfcl._words import count
from brdfcl.data.geometry import bin_centres
from brdfcl.model.lobes.diffraction import LAMBDAS
from brdfcl.report import style as FS
from brdfcl.report.files import writing


def _extent():
    th, td, _ = bin_centres()
    return np.degrees(td), np.degrees(th)


def _save(fig, path):
    tmp = str(path) + ".tmp.png"
    with writing(path):
        fig.savefig(tmp, dpi=FS.DPI)
        Path(tmp).replace(path)


def _draw(build, a, path):
    """Build a figure in the shared style, save it to ``path``; returns the (closed) Figure."""
    plt = FS.pyplot()
    with FS.style():
        fig = build(plt, a)
        try:
            _save(fig, path)
        finally:
            plt.close(fig)
    return fig


def vote_map(g):
    """(3, 90, 90) per-cell vote of the gradient test (brdfcl.report.style.VOTE_*): diffraction
    where a decidable cell is closer to the diffraction prediction, Cook-Torrance where it is
    closer to CT's, undecided elsewhere in the tested region, outside the region otherwise.
    The score of a channel is diffraction / (diffraction + Cook-Torrance) cells."""
    v = np.where(g.region[None], FS.VOTE_UNDECIDED, FS.VOTE_OUTSIDE).astype(np.int8)
    v = np.broadcast_to(v, g.decidable.shape).copy()
    v[g.decidable & ~g.consistent] = FS.VOTE_CT
    v[g.decidable & g.consistent] = FS.VOTE_DIFFRACTION
    return v


def _gradient_figure(plt, a):
    import matplotlib.colors as mc
    from matplotlib.patches import Patch
    g = a.gradient
    x, y = _extent()
    votes = vote_map(g)
    fig, grid = plt.subplots(2, 4, figsize=(FS.FIG_WIDTH, 9.4), constrained_layout=True,
                             gridspec_kw={"width_ratios": (1, 1, 1, 0.55)})
    axes, side = grid[:, :3], grid[:, 3]
    for ax in axes.ravel()[1:]:
        ax.sharex(axes[0, 0])
        ax.sharey(axes[0, 0])
    order = (FS.VOTE_OUTSIDE, FS.VOTE_UNDECIDED, FS.VOTE_CT, FS.VOTE_DIFFRACTION)
    cmap = mc.ListedColormap([FS.VOTE_COLORS[k][1] for k in order])
    norm = mc.BoundaryNorm(np.arange(len(order) + 1) - 0.5, len(order))
    for c, ch in enumerate(FS.CHANNELS):
        ax = axes[0, c]
        ax.pcolormesh(x, y, votes[c], cmap=cmap, norm=norm, shading="auto", rasterized=True)
        n_d = int((votes[c] == FS.VOTE_DIFFRACTION).sum())
        score = "n/a (no decided cell)" if not np.isfinite(g.score[c]) else f"{g.score[c]:.2f}"
        ax.set_title(f"{ch}: score {score}\n= {n_d} diffraction / {count(int(g.n_cells[c]), 'decided cell')}",
                     color=FS.CHANNEL_COLORS[c])
        FS.angle_axes(ax, xlabel=False, ylabel=c == 0)
        ax = axes[1, c]
        ax.set_facecolor(FS.NO_DATA)
        img = np.where(g.significant[c], g.angle_f[c], np.nan)
        im = ax.pcolormesh(x, y, img, cmap=FS.ANGLE_CMAP, vmin=0, vmax=90, shading="auto", rasterized=True)
        ax.contour(x, y, g.region.astype(float), levels=[0.5], colors="w", linewidths=1.5)
        ax.contour(x, y, g.region.astype(float), levels=[0.5], colors="k", linewidths=0.8)
        ax.set_title(f"{ch}: angle of grad p to grad f", color=FS.CHANNEL_COLORS[c])
        FS.angle_axes(ax, ylabel=c == 0)
    handles = [Patch(facecolor=FS.VOTE_COLORS[k][1], edgecolor="0.4", label=FS.VOTE_COLORS[k][0])
               for k in reversed(order)]
    for ax in axes.ravel():
        ax.label_outer()
    for ax in side:
        ax.axis("off")
    side[0].legend(handles=handles, loc="upper left", frameon=False, title="top row: per-cell vote",
                   alignment="left", labelspacing=1.2, borderaxespad=0)
    fig.colorbar(im, cax=side[1].inset_axes((0.0, 0.0, 0.1, 1.0)),
                 label="degrees (0: along the level lines of f)")
    scores = ", ".join(f"{ch} {s:.2f}" if np.isfinite(s) else f"{ch} n/a" for ch, s in zip(FS.CHANNELS, g.score))
    fig.suptitle(f"{a.name}: gradient test at $\\phi_d \\approx 90^\\circ$; scores {scores} "
                 f"(share of decided cells voting diffraction; >= 0.5 supports it)\n"
                 f"bottom: grey = gradient below noise, outline = tested region "
                 f"($\\theta_h \\geq 5^\\circ$, $\\theta_d \\leq 75^\\circ$, $\\theta_i \\leq 80^\\circ$)")
    return fig


def figure_gradient(a, path):
    """Per channel the gradient test's vote per cell (top) and the angle to grad f (bottom)."""
    return _draw(_gradient_figure, a, path)


def wavelength_curves(w, lambdas=LAMBDAS):
    """The curves the wavelength check's spreads (and so its ratio) are computed on, as plotted:
    {"f_c": (x, y, common), "f0": (x, y, common)} with x the bins' geometric centres (f_c in 1/um,
    f0 = 2 sin th cos td), y (3, N_BINS) the scaled per-channel curves (WavelengthCheck.curves and
    .curves_f0, unchanged) and common the bins where every channel has a value (the spread's bins)."""
    mid = np.sqrt(w.edges[1:] * w.edges[:-1])
    out = {}
    for key, x, y in (("f_c", mid, w.curves), ("f0", mid * lambdas[1], w.curves_f0)):
        y = np.asarray(y)
        out[key] = (x, y, np.isfinite(y).all(axis=0))
    return out


def _wavelength_samples(w, lambdas):
    """The samples behind the curves, scaled per channel as their curve: {key: [(x, y)] * 3}."""
    from brdfcl.analysis.wavelength import _binned
    f, q = w.points
    f0 = f[1] * lambdas[1]
    out = {"f_c": [], "f0": []}
    for c in range(3):
        for key, x, edges, curve in (("f_c", f[c], w.edges, w.curves[c]),
                                     ("f0", f0, w.edges * lambdas[1], w.curves_f0[c])):
            with np.errstate(invalid="ignore", divide="ignore"):
                k = np.nanmedian(_binned(x, q[c], edges) / curve)
            pos = q[c] > 0
            out[key].append((x[pos], q[c][pos] / k if np.isfinite(k) and k > 0 else np.full(pos.sum(), np.nan)))
    return out


def _wavelength_figure(plt, a, lambdas=None):
    from brdfcl.model.compose import Model
    w = a.wavelength
    lambdas = lambdas or Model(a.specs["full"]).lambdas
    curves = wavelength_curves(w, lambdas)
    samples = _wavelength_samples(w, lambdas)
    fig, axes = plt.subplots(1, 2, figsize=(FS.FIG_WIDTH, 5.6), constrained_layout=True, sharey=True)
    titles = {"f_c": (f"against $f_c$: spread {w.spread:.3f}",
                      r"$f_c = 2\,\sin\theta_h \cos\theta_d\, /\, \lambda_c$ (1/$\mu$m)"),
              "f0": (f"against $2 \\sin\\theta_h \\cos\\theta_d$ (no wavelength): spread {w.spread_f0:.3f}",
                     r"$2\,\sin\theta_h \cos\theta_d$ (dimensionless)")}
    for ax, key in zip(axes, ("f_c", "f0")):
        x, y, common = curves[key]
        for c in range(3):
            sx, sy = samples[key][c]
            ax.plot(sx, sy, ".", ms=1.5, alpha=0.12, color=FS.CHANNEL_COLORS[c], rasterized=True)
        for c, ch in enumerate(FS.CHANNELS):
            ok = np.isfinite(y[c]) & (y[c] > 0)
            ax.plot(x[ok], y[c][ok], "-", lw=2, color=FS.CHANNEL_COLORS[c],
                    label=f"{ch} ($\\lambda$ = {lambdas[c]:.3f} $\\mu$m)")
            ax.plot(x[ok & common], y[c][ok & common], "o", ms=4, color=FS.CHANNEL_COLORS[c])
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(titles[key][0])
        ax.set_xlabel(titles[key][1])
        ax.grid(True, which="major", color="0.9", lw=0.8)
    from matplotlib.lines import Line2D
    extra = [Line2D([], [], ls="", marker="o", ms=4, color="0.3", label="bins in the spread (all channels)"),
             Line2D([], [], ls="", marker=".", ms=5, color="0.3", alpha=0.5, label="samples, scaled as their curve")]
    h, _ = axes[0].get_legend_handles_labels()
    fig.legend(handles=h + extra, loc="outside lower center", ncols=5, frameon=False,
               title="lines: median of each bin, scaled per channel (the curves the spreads are computed on)")
    axes[0].set_ylabel(r"$p - \rho_d/\pi$, scaled per channel (relative)")
    law = a.law_ratio
    says = ("no value" if not np.isfinite(law) else
            "< 1: the wide angles fit better with each channel's wavelength, as diffraction predicts" if law < 1
            else ">= 1: they fit no better with each channel's wavelength")
    fig.suptitle(f"{a.name}: the wavelength law pictured at $\\phi_d \\approx 90^\\circ$ (curve collapse: ratio "
                 f"of spreads {w.spread:.3f} / {w.spread_f0:.3f} = {w.ratio:.2f}, not used by the verdict)\n"
                 f"law test (wide-angle error with $\\lambda_c$ / with one $\\lambda$) {law:.3f}: {says}")
    return fig


def figure_wavelength(a, path):
    """The scaled per-channel curves the spread ratio is computed on, against f_c and f0."""
    return _draw(_wavelength_figure, a, path)


COMPONENTS = (("measured", "measured"), ("diffuse_diffraction", "diffuse + diffraction"),
              ("ct", "Cook-Torrance"), ("full", "full model"))


def residual(a):
    """(3, 90, 90) ln(measured / full model) on the phi_d ~ 90 deg slice, NaN where either is not > 0."""
    m, f = a.slices["measured"], a.slices["full"]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where((m > 0) & (f > 0), np.log(np.where(m > 0, m, 1) / np.where(f > 0, f, 1)), np.nan)


def _components_figure(plt, a):
    import matplotlib.colors as mc
    x, y = _extent()
    inner = (x <= 75)[None, None, :]                 # colour ranges from outside the grazing spike
    stack = np.stack([a.slices[k] for k in ("measured", "full")])     # the lobes may lie far below
    vals = stack[np.broadcast_to(inner[None], stack.shape) & np.isfinite(stack) & (stack > 0)]
    # the top 1% (the specular peak's first theta_h bins) saturates, for contrast at wide angles
    vmin, vmax = (np.percentile(vals, 1), np.percentile(vals, 99)) if vals.size else (1e-3, 1)
    norm = mc.LogNorm(vmin=max(vmin, 1e-6, vmax * 1e-8), vmax=vmax)
    res = residual(a)
    rin = np.abs(res[np.broadcast_to(inner, res.shape) & np.isfinite(res)])
    lim = float(np.clip(np.percentile(rin, 99), 0.05, 3.0)) if rin.size else 1.0
    fig, axes = plt.subplots(3, 5, figsize=(FS.FIG_WIDTH, 11.0), constrained_layout=True,
                             sharex=True, sharey=True)
    for c, ch in enumerate(FS.CHANNELS):
        for j, (k, title) in enumerate(COMPONENTS):
            ax = axes[c, j]
            ax.set_facecolor(FS.NO_DATA)
            img = np.where(a.slices[k][c] > 0, a.slices[k][c], np.nan)
            im = ax.pcolormesh(x, y, img, cmap=FS.VALUE_CMAP, norm=norm, shading="auto", rasterized=True)
            ax.set_title(f"{ch}: {title}", color=FS.CHANNEL_COLORS[c])
        ax = axes[c, 4]
        ax.set_facecolor(FS.NO_DATA)
        rim = ax.pcolormesh(x, y, res[c], cmap=FS.RESIDUAL_CMAP, vmin=-lim, vmax=lim, shading="auto",
                            rasterized=True)
        r = res[c][np.isfinite(res[c]) & inner[0]]
        rms = f"rms {np.sqrt(np.mean(r ** 2)):.2g}" if r.size else "no data"
        ax.set_title(f"{ch}: residual ({rms})", color=FS.CHANNEL_COLORS[c])
        for j in range(5):
            FS.angle_axes(axes[c, j], xlabel=c == 2, ylabel=j == 0)
            axes[c, j].set_xticks(range(0, 91, 30))
            axes[c, j].set_yticks(range(0, 91, 30))
    fig.colorbar(im, ax=axes[:, :4], location="bottom", label="BRDF (1/sr), log scale",
                 shrink=0.6, aspect=40, extend="both")
    fig.colorbar(rim, ax=axes[:, 4], location="bottom", label="ln(measured / fitted)\nred: data above the fit",
                 aspect=10, extend="both", ticks=[-lim, 0, lim], format="%.2g")
    rmse = a.fits["full"].errors.get("rmse_log") if "full" in getattr(a, "fits", {}) else None
    fit = f"; rmse_log {rmse:.3g}" if rmse is not None and np.isfinite(rmse) else ""
    fig.suptitle(f"{a.name}: separate components of {a.specs['full']} at $\\phi_d \\approx 90^\\circ${fit}\n"
                 f"rows: channels; columns: measured, the fitted lobes, the full fit, and the residual "
                 f"(rms over $\\theta_d \\leq 75^\\circ$; grey: no data)")
    return fig


def figure_components(a, path):
    """Per channel (rows R, G, B): measured, diffuse + diffraction, Cook-Torrance, full, residual."""
    return _draw(_components_figure, a, path)
