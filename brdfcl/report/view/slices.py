"""Slice plots of a fit against its measured table: BRDF x cos(theta_o) against the outgoing
angle, for several incidence angles, per channel, on a log scale; and the fitted model's lobes
one by one on the in-plane slice.  Cartesian or polar (matplotlib, Agg).

Convention: the light comes from azimuth phi_i = 0 at theta_i.  In the plane of incidence the
outgoing angle is signed: theta_o < 0 on the light's side (theta_o = -theta_i is back towards
the light), theta_o > 0 on the far side (theta_o = theta_i is the mirror direction).  The
out-of-plane slices take theta_o in [0, 90) deg at a fixed phi_o - phi_i (90 deg: perpendicular
to the plane of incidence; 135 deg: half way to the mirror side, phi_o - phi_i = 180 deg).
Measured values are looked up in the table as brdfcl.report.view.sphere does (trilinear, on log values).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.ticker import NullLocator

from brdfcl.data.merl import MerlTable
from brdfcl.model.lobes.cells import Cells
from brdfcl.report.view.lookup import table_lookup
from brdfcl.report.view.sphere import as_model, save_figure

INCIDENCE_DEG = (0.0, 30.0, 60.0, 75.0)
PLANES = ((None, "in the plane of incidence"), (90.0, r"$\phi_o - \phi_i$ = 90 deg"),
          (135.0, r"$\phi_o - \phi_i$ = 135 deg"))
LOBE_STYLE = {"diffuse": ("diffuse", "tab:orange"), "diffraction": ("diffraction", "tab:purple"),
              "reflection": ("Cook-Torrance", "tab:blue")}
"""Label and colour of a lobe, by role (brdfcl.model.lobes.lobe.ROLES)."""


def lobe_style(model, lobe):
    """(label, colour) of one of ``model``'s lobes: its role's; where the model holds several lobes
    of that role, the label names the lobe's prefix and the colour is the role's for the first only."""
    label, color = LOBE_STYLE.get(lobe.role, (lobe.prefix, None))
    same = model.lobes_with_role(lobe.role)
    if len(same) > 1:
        label = f"{label} ({lobe.prefix})"
        color = color if lobe is same[0] else None
    return label, color
CHANNELS = ("R", "G", "B")
_POLAR = r" (polar: angle $\theta_o$ from the normal, up; radius log)"
DECADES = 9                       # y range: the largest value down to this many decades


def outgoing_deg(dphi=None, step=0.25):
    """Sampled theta_o (deg): signed over (-90, 90) in plane, [0, 90) out of plane."""
    return np.arange(-89.75 if dphi is None else 0.0, 89.9, step)


def slice_directions(theta_i_deg, theta_o_deg, dphi_deg=None):
    """(wi, wo) (n, 3) of one slice in the local frame (n = z), light at azimuth 0."""
    ti, to = np.radians(theta_i_deg), np.radians(np.asarray(theta_o_deg, dtype=float))
    phi = np.where(to < 0, 0.0, np.pi) if dphi_deg is None else np.full(to.shape, np.radians(dphi_deg))
    so = np.sin(np.abs(to))
    wo = np.stack([so * np.cos(phi), so * np.sin(phi), np.cos(to)], -1)
    wi = np.broadcast_to([np.sin(ti), 0.0, np.cos(ti)], wo.shape)
    return wi, wo


def only_lobes(model, values, keep):
    """``values`` (a vector) with every amplitude outside the lobes ``keep`` zeroed."""
    return model.only_lobes(model.as_dict(values), keep)


def slice_values(table, model, values, theta_i_deg, theta_o_deg, dphi_deg=None, lobes=False):
    """BRDF x cos(theta_o) (3, n) on one slice: {"measured", "fitted"} and, with ``lobes``,
    one entry per lobe of the model (its prefix: diffuse, diffraction, ct, ct2, ...)."""
    wi, wo = slice_directions(theta_i_deg, theta_o_deg, dphi_deg)
    cos = wo[:, 2]
    cells = Cells.from_directions(wi, wo)
    out = {"measured": table_lookup(table, wi, wo) * cos,
           "fitted": model.reference(cells, values, jacobian=False) * cos}
    for lb in model.lobes if lobes else ():
        out[lb.prefix] = model.reference(cells, only_lobes(model, values, (lb.prefix,)), jacobian=False) * cos
    return out


def _axes(plt, rows, cols, polar, size):
    kw = {"subplot_kw": {"projection": "polar"}} if polar else {"sharex": "row", "sharey": "row"}
    fig, axes = plt.subplots(rows, cols, figsize=size, squeeze=False, constrained_layout=True, **kw)
    for ax in axes.ravel():
        if polar:                 # the normal up, positive theta_o to the right, radius log
            ax.set_theta_zero_location("N")
            ax.set_theta_direction(-1)
            ax.set_thetamin(-90)
            ax.set_thetamax(90)
            ax.set_rscale("log")
        else:
            ax.set_yscale("log")
            ax.grid(True, which="major", color="0.9", lw=0.6)
        ax.yaxis.set_minor_locator(NullLocator())       # a grid line per decade reads best (and fast)
    return fig, axes


def _plot(ax, polar, x_deg, y, *fmt, **kw):
    return ax.plot(np.radians(x_deg) if polar else x_deg, y, *fmt, **kw)


def _limits(axes, polar, curves, dphi):
    """One value range for a row of panels: from the top of every curve down to where the
    lowest quarter of the weakest curve starts (so that every lobe shows), at most DECADES."""
    pos = [c[np.isfinite(c) & (c > 0)] for c in (np.ravel(a) for a in curves)]
    pos = [c for c in pos if c.size]
    hi = 2 * max(c.max() for c in pos) if pos else 1.0
    lo = max(min(np.percentile(c, 25) for c in pos) / 3 if pos else 1e-3, hi * 10.0 ** -DECADES)
    for ax in axes:
        if polar:                 # radius labels every second decade, between the -45 deg spokes
            ax.set_rlim(lo, hi)
            ax.set_yticks(10.0 ** np.arange(np.ceil(np.log10(lo)), np.log10(hi), 2))
            ax.set_rlabel_position(-52.5 if dphi is None else 37.5)
            ax.tick_params(axis="y", labelsize=7)
        else:
            ax.set_ylim(lo, hi)
            ax.set_xlim(-90 if dphi is None else 0, 90)
            ax.set_xticks(np.arange(-90 if dphi is None else 0, 91, 30))


def _light(ax, polar, theta_i, color):
    """A triangle on the rim at -theta_i: where the light comes from."""
    ax.plot([np.radians(-theta_i) if polar else -theta_i], [1.0], "v", color=color, ms=7, clip_on=False,
            transform=ax.get_xaxis_transform(), mec="k", mew=0.5)


def _measured(ax, polar, x, y, color, **kw):
    """Measured values: a wide translucent band with hollow markers every 3 deg."""
    _plot(ax, polar, x, y, color=color, lw=4, alpha=0.3)
    _plot(ax, polar, x[::12], y[::12], "o", color=color, ms=3.5, mfc="none", **kw)


def figure_slices(path, name, table, model, values, polar=False):
    """Rows: the in-plane and out-of-plane slices; columns: R, G, B; one colour per theta_i."""
    import matplotlib.pyplot as plt
    fig, axes = _axes(plt, len(PLANES), 3, polar, (15, 8.5) if polar else (14, 11))
    colors = plt.get_cmap("viridis")(np.linspace(0.0, 0.85, len(INCIDENCE_DEG)))
    for row, (dphi, title) in enumerate(PLANES):
        to = outgoing_deg(dphi)
        curves = [slice_values(table, model, values, ti, to, dphi) for ti in INCIDENCE_DEG]
        for c in range(3):
            ax = axes[row, c]
            for ti, col, cv in zip(INCIDENCE_DEG, colors, curves):
                if dphi is None:
                    _light(ax, polar, ti, col)
                _measured(ax, polar, to, cv["measured"][c], col)
                _plot(ax, polar, to, cv["fitted"][c], color=col, lw=1.2, label=rf"$\theta_i$ = {ti:.0f} deg")
            ax.set_title(f"{CHANNELS[c]}, {title}", fontsize=10)
            _label(ax, polar, dphi, c)
        _limits(axes[row], polar, [cv[k] for cv in curves for k in cv], dphi)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    handles += [plt.Line2D([], [], color="0.4", lw=4, alpha=0.3, marker="o", mfc="none", ms=3.5),
                plt.Line2D([], [], color="0.4", lw=1.2),
                plt.Line2D([], [], ls="none", marker="v", color="0.6", mec="k", mew=0.5, ms=7)]
    labels += ["measured (table)", f"fitted: {model.spec}", r"light direction ($-\theta_i$, in plane)"]
    fig.legend(handles, labels, loc="outside lower center", ncol=3, fontsize=9)
    fig.suptitle(rf"{name}: BRDF $\times\cos\theta_o$ against the outgoing angle, measured against "
                 rf"fitted{_POLAR if polar else ''}" "\n"
                 r"($\theta_o < 0$: the light's side; $\theta_o = \theta_i$: the mirror direction)")
    save_figure(fig, path)


def figure_lobes(path, name, table, model, values, polar=False):
    """Rows: R, G, B; columns: theta_i; the fitted lobes separately on the in-plane slice."""
    import matplotlib.pyplot as plt
    cols = len(INCIDENCE_DEG)
    fig, axes = _axes(plt, 3, cols, polar, (17, 7.5) if polar else (16, 10))
    to = outgoing_deg()
    curves = [slice_values(table, model, values, ti, to, lobes=True) for ti in INCIDENCE_DEG]
    for col, (ti, cv) in enumerate(zip(INCIDENCE_DEG, curves)):
        for c in range(3):
            ax = axes[c, col]
            _measured(ax, polar, to, cv["measured"][c], "0.45", label="measured (table)")
            _plot(ax, polar, to, cv["fitted"][c], color="k", lw=1.2, label="fitted, all lobes")
            for lb in model.lobes:
                label, color = lobe_style(model, lb)
                _plot(ax, polar, to, cv[lb.prefix][c], "--", color=color, lw=1.4, label=label)
            ax.set_title(rf"{CHANNELS[c]}, $\theta_i$ = {ti:.0f} deg", fontsize=10)
            _light(ax, polar, ti, "0.6")
            _label(ax, polar, None, c if col == 0 else None)
    for c in range(3):
        _limits(axes[c], polar, [cv[k][c] for cv in curves for k in cv], None)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=9)
    fig.suptitle(f"{name}: the fitted lobes of {model.spec} one by one, in the plane of incidence"
                 rf"{_POLAR if polar else ''}" "\n"
                 r"BRDF $\times\cos\theta_o$; $\theta_o < 0$: the light's side")
    save_figure(fig, path)


def _label(ax, polar, dphi, channel):
    what = r"$\theta_o$ (deg)" + ("" if dphi is None else rf" at $\phi_o - \phi_i$ = {dphi:.0f} deg")
    if polar:                     # the angles are written on the rim
        return
    ax.set_xlabel(what)
    if channel is not None:
        ax.set_ylabel(r"BRDF $\times\cos\theta_o$ (1/sr)")


def write_slices(out_dir, name, table, model, values, polar=False):
    """``NAME-slices.png`` and ``NAME-lobes.png`` (and ``-polar`` versions with ``polar``).
    ``table``: a MerlTable or (3, N_CELLS) BRDF array; ``values``: a vector or {name: value}."""
    import matplotlib
    matplotlib.use("Agg")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    model, values = as_model(model, values)
    brdf = np.ascontiguousarray((table.brdf() if isinstance(table, MerlTable) else table).T).T
    paths = []
    for suffix, pol in (("", False), ("-polar", True)) if polar else (("", False),):
        paths += [out_dir / f"{name}-slices{suffix}.png", out_dir / f"{name}-lobes{suffix}.png"]
        figure_slices(paths[-2], name, brdf, model, values, pol)
        figure_lobes(paths[-1], name, brdf, model, values, pol)
    return paths
