"""Figures of scattered spectral samples, in the shared style (brdfcl.report.style).

* ``figure_in_plane``: measured samples in the plane of incidence against the fitted model, one
  panel per incidence angle, a few bands coloured by wavelength: what a fit of scattered data
  looks like where a reader can check it (a report page of a fit, and an analysis).
* ``figure_spectral``: the wavelength check of brdfcl.analysis.spectral: the wide-angle data left
  for diffraction (data minus the fitted diffuse and reflection lobes) against f_c = f0 / lambda_c
  and against f0, every sample coloured by its band's wavelength, with the scaled per-band median
  curves the spreads are computed on.
"""
from __future__ import annotations

import numpy as np

from brdfcl._words import count
from brdfcl.model.lobes.cells import Cells
from brdfcl.report import style as FS
from brdfcl.report.figures import _draw

IN_PLANE_DEG = 2.0            # |phi_o - phi_i| within this of 0 or 180 deg: in the plane of incidence
MAX_PANELS = 4
MAX_BANDS = 5


def wavelength_colour(lam_um, lo=0.38, hi=0.72):
    """A colour for a wavelength (um): the spectral map from violet to red."""
    import matplotlib
    return matplotlib.colormaps["turbo"]((np.clip(lam_um, lo, hi) - lo) / (hi - lo))


def bands_to_show(lambdas, n=MAX_BANDS) -> list[int]:
    """Up to n channel indices spread evenly over the bands."""
    return sorted(set(np.linspace(0, len(lambdas) - 1, min(n, len(lambdas))).round().astype(int).tolist()))


def incidence_first(samples) -> tuple[np.ndarray, np.ndarray]:
    """(theta of the incidence, theta of the other direction) of each sample, radians: the
    direction an instrument held fixed is the incidence, the one with fewer distinct angles (by
    reciprocity either of wi, wo may be; ALTA files, for one, write the light second)."""
    ti, to = samples.theta_i, samples.theta_o
    if np.unique(np.round(to, 4)).size < np.unique(np.round(ti, 4)).size:
        return to, ti
    return ti, to


def in_plane(samples, tol_deg=IN_PLANE_DEG):
    """(mask, signed theta_o in degrees) of the samples in the plane of incidence: theta_o > 0 on
    the specular side (phi_o = phi_i + 180 deg), < 0 on the side of the light (theta_o: the angle
    of the direction that is not the incidence, ``incidence_first``)."""
    d = np.degrees(np.mod(samples.phi_o - samples.phi_i + np.pi, 2 * np.pi) - np.pi)
    fwd, back = np.abs(np.abs(d) - 180) <= tol_deg, np.abs(d) <= tol_deg
    return fwd | back, np.where(back, -1.0, 1.0) * np.degrees(incidence_first(samples)[1])


def incidence_panels(samples, mask, n=MAX_PANELS) -> list[float]:
    """Up to n incidence angles (radians, ``incidence_first``) with at least 3 in-plane samples,
    spread over their range."""
    ti = np.round(incidence_first(samples)[0][mask], 4)
    values, counts = np.unique(ti, return_counts=True)
    values = values[counts >= 3]
    if values.size == 0:
        return []
    return [float(values[i]) for i in bands_to_show(values, n)]


def model_in_plane(model, params, theta_i, theta_o_signed_deg):
    """(C, n) model values in the plane of incidence (phi_i = 0) at signed theta_o (degrees)."""
    to = np.radians(np.abs(theta_o_signed_deg))
    po = np.where(theta_o_signed_deg >= 0, np.pi, 0.0)
    ti = np.full(to.size, theta_i)
    wi = np.stack([np.sin(ti), np.zeros_like(ti), np.cos(ti)], axis=1)
    wo = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)], axis=1)
    values = model.only_lobes(params, None) if isinstance(params, dict) else params
    return model.reference(Cells.from_directions(wi, wo), values, jacobian=False)


def _in_plane_figure(plt, what):
    samples, model, params, title = what
    mask, signed = in_plane(samples)
    panels = incidence_panels(samples, mask)
    lam = np.asarray(samples.wavelengths)
    bands = bands_to_show(lam)
    ncol = max(len(panels), 1)
    fig, axes = plt.subplots(1, ncol, figsize=(FS.FIG_WIDTH, 5.0), constrained_layout=True, squeeze=False)
    grid = np.linspace(-89.0, 89.0, 713)
    incidence = incidence_first(samples)[0]
    for ax, ti in zip(axes[0], panels):
        here = mask & (np.abs(incidence - ti) < 1e-4)
        fitted = model_in_plane(model, params, ti, grid)
        for c in bands:
            col = wavelength_colour(lam[c])
            v = samples.values[here, c]
            ok = v > 0
            ax.plot(signed[here][ok], v[ok], "o", ms=4.5, color=col, mec="k", mew=0.3)
            ax.plot(grid, np.where(fitted[c] > 0, fitted[c], np.nan), "-", lw=1.4, color=col,
                    label=f"{lam[c] * 1000:.0f} nm")
        ax.axvline(np.degrees(ti), color="0.6", lw=0.8, ls=":")
        ax.set_yscale("log")
        ax.set_xlim(-90, 90)
        ax.set_xticks(range(-90, 91, 30))
        ax.set_title(rf"$\theta_i$ = {np.degrees(ti):.0f}$^\circ$ ({count(int(here.sum()), 'sample')})")
        ax.set_xlabel(r"$\theta_o$ (degrees)")
        ax.grid(True, which="major", color="0.9", lw=0.8)
    if not panels:
        _along_theta_h(axes[0, 0], samples, model, params, bands)
    axes[0, 0].set_ylabel("BRDF (1/sr), log scale")
    h, labels = axes[0, 0].get_legend_handles_labels()
    if h:
        key = ("points: measured samples; lines: the fitted model; dotted: the mirror direction; "
               r"$\theta_o$ < 0: on the side of the light") if panels else \
            "points: measured samples; lines: the fitted model at the same directions"
        fig.legend(h, labels, loc="outside lower center", ncols=len(bands), frameon=False, title=key)
    fig.suptitle(title)
    return fig


def _along_theta_h(ax, samples, model, params, bands):
    """The panel of samples no incidence angle groups (a 1-D slice, every sample its own
    incidence): measured and fitted at each sample's own directions, against theta_h."""
    lam = np.asarray(samples.wavelengths)
    values = model.only_lobes(params, None) if isinstance(params, dict) else params
    fitted = model.reference(Cells.from_directions(samples.wi, samples.wo), values, jacobian=False)
    th = np.degrees(np.arccos(np.clip(Cells.from_directions(samples.wi, samples.wo).ch, -1.0, 1.0)))
    order = np.argsort(th)
    for c in bands:
        col = wavelength_colour(lam[c])
        v = samples.values[order, c]
        ok = v > 0
        ax.plot(th[order][ok], v[ok], "o", ms=4.5, color=col, mec="k", mew=0.3)
        f = fitted[c][order]
        ax.plot(th[order], np.where(f > 0, f, np.nan), "-", lw=1.4, color=col, label=f"{lam[c] * 1000:.0f} nm")
    ax.set_yscale("log")
    ax.set_xlim(0, 90)
    ax.set_xlabel(r"$\theta_h$ (degrees)")
    ax.set_title(f"no incidence angle with 3 samples: all {count(samples.n_samples, 'sample')}, "
                 "fitted at their own directions")
    ax.grid(True, which="major", color="0.9", lw=0.8)


def figure_in_plane(samples, model, params, path, title=None):
    """Measured against fitted in the plane of incidence (``params``: {name: value} or the
    model's vector)."""
    title = title or f"{samples.name}: measured and fitted in the plane of incidence, {model.spec}"
    return _draw(_in_plane_figure, (samples, model, params, title), path)


def _spectral_figure(plt, a):
    s = a.spectral
    lam = s.wavelengths
    f0, q = s.points
    fig, axes = plt.subplots(1, 2, figsize=(FS.FIG_WIDTH, 5.6), constrained_layout=True, sharey=True)
    mid = np.sqrt(s.edges[1:] * s.edges[:-1])
    ref = lam[lam.size // 2]
    import matplotlib.patheffects as pe
    from matplotlib.ticker import NullFormatter

    from brdfcl.analysis.wavelength import _binned
    outline = [pe.Stroke(linewidth=2.6, foreground="k"), pe.Normal()]
    for ax, key in zip(axes, ("f_c", "f0")):
        for c in range(lam.size):
            x = f0 / lam[c] if key == "f_c" else f0
            pos = q[c] > 0
            ax.scatter(x[pos], q[c][pos], s=3, color=wavelength_colour(lam[c]), alpha=0.35, lw=0,
                       rasterized=True)
        # the scaled band curves of the spread, at the level of the middle band's own medians
        m = lam.size // 2
        x_bins = mid if key == "f_c" else mid * ref
        curves = s.curves if key == "f_c" else s.curves_f0
        with np.errstate(invalid="ignore", divide="ignore"):
            raw = np.log(_binned(f0 / lam[m] if key == "f_c" else f0, q[m], s.edges * (1 if key == "f_c" else ref)))
            level = np.exp(np.nanmean(raw - np.log(curves[m])))
        for c in range(lam.size):
            y = curves[c] * level
            ok = np.isfinite(y) & (y > 0)
            ax.plot(x_bins[ok], y[ok], "-", lw=1.6, color=wavelength_colour(lam[c]), path_effects=outline)
        if key == "f_c":
            ax.set_xlabel(r"$f_c = 2\,\sin\theta_h \cos\theta_d\, /\, \lambda_c$ (1/$\mu$m)")
            ax.set_title(f"against $f_c$: spread of the scaled band medians {s.spread:.3f}")
        else:
            ax.set_xlabel(r"$f_0 = 2\,\sin\theta_h \cos\theta_d$ (no wavelength)")
            ax.set_title(f"against $f_0$: spread {s.spread_f0:.3f} (bins at $f_0$ = f x {ref:.2f} um)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="major", color="0.9", lw=0.8)
    axes[0].set_ylabel(r"data $-$ fitted diffuse and reflection lobes (1/sr)")
    import matplotlib as mpl
    sm = mpl.cm.ScalarMappable(cmap="turbo", norm=mpl.colors.Normalize(380, 720))
    fig.colorbar(sm, ax=axes, location="right", label="wavelength (nm)", shrink=0.8)
    collapse = "collapse better against $f_c$" if s.ratio < 1 else "do not collapse better against $f_c$"
    law = a.law_ratio
    n = f"{s.exponent:.2f} +- {s.exponent_se:.2f}" if np.isfinite(s.exponent) else "n/a"
    fig.suptitle(f"{a.name}: wavelength check over {count(lam.size, 'band')} "
                 f"({count(s.n_wide, 'wide-angle sample')}; lines: the scaled band medians)\n"
                 f"residual band curves: ratio of spreads {s.ratio:.2f}, they {collapse}; "
                 f"wavelength law (wide-angle error with $\\lambda_c$ / with one $\\lambda$): {law:.3f}\n"
                 f"fitted diffraction amplitude ~ $\\lambda^{{-n}}$, n = {n} (4 on a spectrally flat surface)")
    return fig


def figure_spectral(a, path):
    """The spectral wavelength check of a SampleAnalysis (nothing when it has none)."""
    if a.spectral is None:
        return None
    return _draw(_spectral_figure, a, path)
