"""Slice plots of a fit against its measured table: BRDF x cos(theta_o) against the outgoing
angle, for several incidence angles, per channel, on a log scale; and the fitted model's lobes
one by one on the in-plane slice (SVG, brdfcl.report.view.svgplot).

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

from brdfcl.data.merl import MerlTable
from brdfcl.model.lobes.cells import Cells
from brdfcl.report.files import atomic_write_text
from brdfcl.report.view.lookup import table_lookup
from brdfcl.report.view.sphere import as_model
from brdfcl.report.view.svgplot import Figure

INCIDENCE_DEG = (0.0, 30.0, 60.0, 75.0)
PLANES = ((None, "in the plane of incidence"), (90.0, "\u03c6o \u2212 \u03c6i = 90 deg"),
          (135.0, "\u03c6o \u2212 \u03c6i = 135 deg"))
INCIDENCE_COLORS = ("#440154", "#375b8d", "#1fa188", "#9bd93c")     # viridis, 0 .. 0.85
LOBE_STYLE = {"diffuse": ("diffuse", "#ff7f0e"), "diffraction": ("diffraction", "#9467bd"),
              "reflection": ("Cook-Torrance", "#1f77b4")}
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
OTHER_LOBES = ("#8c564b", "#e377c2", "#17becf", "#bcbd22")     # lobes of a role already coloured
CHANNELS = ("R", "G", "B")
MEASURED, GREY = "#737373", "#999999"
THETA_O = "\u03b8o (deg)"
Y_LABEL = "BRDF \u00d7 cos \u03b8o (1/sr)"
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


def slice_curves(table, model, values):
    """{(dphi, theta_i): {"theta_o", "measured", "fitted", and per lobe on the in-plane slices}}
    of every slice the figures show, from `slice_values`."""
    out = {}
    for dphi, _ in PLANES:
        to = outgoing_deg(dphi)
        for ti in INCIDENCE_DEG:
            out[dphi, ti] = {"theta_o": to, **slice_values(table, model, values, ti, to, dphi, lobes=dphi is None)}
    return out


def _limits(curves):
    """One value range for a row of panels: from the top of every curve down to where the
    lowest quarter of the weakest curve starts (so that every lobe shows), at most DECADES."""
    quartiles, tops = [], []
    by_size: dict[int, list] = {}
    for c in curves:
        a = np.ravel(c)
        by_size.setdefault(a.size, []).append(a)
    for group in by_size.values():          # curves of one length: one sort
        a = np.stack(group)
        valid = np.isfinite(a) & (a > 0)
        k = valid.sum(1)
        a = np.sort(np.where(valid, a, np.inf), axis=1)[k > 0]
        k = k[k > 0]
        at = (k - 1) * 0.25                 # numpy's default ("linear") percentile
        lo = np.floor(at).astype(int)
        rows = np.arange(k.size)
        hi_i = np.minimum(lo + 1, k - 1)
        quartiles += list(a[rows, lo] + (at - lo) * (a[rows, hi_i] - a[rows, lo]))
        tops += list(a[rows, k - 1])
    hi = 2 * max(tops) if tops else 1.0
    lo = max(min(quartiles) / 3 if quartiles else 1e-3, hi * 10.0 ** -DECADES)
    return lo, hi


def _measured(panel, x, y, color):
    """Measured values: a wide translucent band with hollow markers every 3 deg."""
    panel.line(x, y, color, width=4, opacity=0.3)
    panel.markers(x[::12], y[::12], color)


def _ticks(dphi):
    return tuple(range(-90 if dphi is None else 0, 91, 30))


def slices_svg(name, spec, curves) -> str:
    """Rows: the in-plane and out-of-plane slices; columns: R, G, B; one colour per theta_i."""
    fig = Figure(len(PLANES), 3, title=[
        f"{name}: BRDF \u00d7 cos \u03b8o against the outgoing angle, measured against fitted",
        "(\u03b8o < 0: the light's side; \u03b8o = \u03b8i: the mirror direction)"])
    for row, (dphi, title) in enumerate(PLANES):
        row_curves = [curves[dphi, ti] for ti in INCIDENCE_DEG]
        y_range = _limits([cv[k] for cv in row_curves for k in ("measured", "fitted")])
        for c in range(3):
            p = fig.panel(row, c, x_range=(-90 if dphi is None else 0, 90), y_range=y_range,
                          title=f"{CHANNELS[c]}, {title}", xticks=_ticks(dphi), ylabel=Y_LABEL if c == 0 else "",
                          xlabel=THETA_O + ("" if dphi is None else f" at \u03c6o \u2212 \u03c6i = {dphi:.0f} deg"))
            for ti, col, cv in zip(INCIDENCE_DEG, INCIDENCE_COLORS, row_curves):
                if dphi is None:
                    p.light(-ti, col)
                _measured(p, cv["theta_o"], cv["measured"][c], col)
                p.line(cv["theta_o"], cv["fitted"][c], col)
    fig.legend = [(f"\u03b8i = {ti:.0f} deg", "line", col) for ti, col in zip(INCIDENCE_DEG, INCIDENCE_COLORS)]
    fig.legend += [("measured (table)", "band", MEASURED), (f"fitted: {spec}", "line", "#555555"),
                   ("light direction (\u2212\u03b8i, in plane)", "light", GREY)]
    return fig.svg()


def lobes_svg(name, model, curves) -> str:
    """Rows: R, G, B; columns: theta_i; the fitted lobes separately on the in-plane slice."""
    fig = Figure(3, len(INCIDENCE_DEG), panel_size=(270, 180), title=[
        f"{name}: the fitted lobes of {model.spec} one by one, in the plane of incidence",
        "BRDF \u00d7 cos \u03b8o; \u03b8o < 0: the light's side"])
    styles = [lobe_style(model, lb) for lb in model.lobes]
    colors = [col or OTHER_LOBES[i % len(OTHER_LOBES)] for i, (_, col) in enumerate(styles)]
    for c in range(3):
        row = [curves[None, ti] for ti in INCIDENCE_DEG]
        y_range = _limits([cv[k][c] for cv in row for k in ["measured", "fitted"] + [lb.prefix for lb in model.lobes]])
        for col, (ti, cv) in enumerate(zip(INCIDENCE_DEG, row)):
            p = fig.panel(c, col, x_range=(-90, 90), y_range=y_range, xticks=_ticks(None), xlabel=THETA_O,
                          title=f"{CHANNELS[c]}, \u03b8i = {ti:.0f} deg", ylabel=Y_LABEL if col == 0 else "")
            _measured(p, cv["theta_o"], cv["measured"][c], MEASURED)
            p.line(cv["theta_o"], cv["fitted"][c], "black")
            for lb, color in zip(model.lobes, colors):
                p.line(cv["theta_o"], cv[lb.prefix][c], color, width=1.4, dash="5,3")
            p.light(-ti, GREY)
    fig.legend = [("measured (table)", "band", MEASURED), ("fitted, all lobes", "line", "black")]
    fig.legend += [(label, "dash", color) for (label, _), color in zip(styles, colors)]
    return fig.svg()


def write_slice_figures(out_dir, name, model, curves):
    """``NAME-slices.svg`` and ``NAME-lobes.svg`` from ``curves`` (`slice_curves`' form)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{name}-slices.svg", out_dir / f"{name}-lobes.svg"]
    atomic_write_text(paths[0], slices_svg(name, model.spec, curves))
    atomic_write_text(paths[1], lobes_svg(name, model, curves))
    return paths


def write_slices(out_dir, name, table, model, values):
    """The slice figures (`write_slice_figures`) of a fit against its table, each value computed
    here (the report takes them from brdfcl.report.view.views' plan instead).  ``table``: a
    MerlTable or (3, N_CELLS) BRDF array; ``values``: a vector or {name: value}."""
    model, values = as_model(model, values)
    brdf = np.ascontiguousarray((table.brdf() if isinstance(table, MerlTable) else table).T).T
    return write_slice_figures(out_dir, name, model, slice_curves(brdf, model, values))
