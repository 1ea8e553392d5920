"""A measured MERL table at any pair of directions: the table's own (theta_h, theta_d, phi_d)
coordinates of a direction pair (``rusinkiewicz``) and an interpolated lookup (``table_lookup``),
what the lit spheres and the slice plots show of the measurement."""
from __future__ import annotations

import numpy as np

from brdfcl.data.geometry import index_coordinates, nearest_cells, rusinkiewicz
from brdfcl.data.merl import N_PD, N_TD, N_TH, MerlTable

__all__ = ["corners", "interpolate", "nearest_cells", "rusinkiewicz", "table_lookup"]


def corners(wi, wo):
    """Trilinear interpolation of the table at direction pairs (n, 3): the cell indices (8, n) of
    the neighbouring bin centres and their weights (8, n); phi_d is periodic (reciprocity).
    Computed once for points looked up in many tables (`interpolate`)."""
    u = index_coordinates(wi, wo)
    lo = [np.minimum(np.floor(x).astype(int), n - 2) for x, n in zip(u, (N_TH, N_TD, N_PD + 1))]
    fr = [x - i for x, i in zip(u, lo)]
    index, weight = np.empty((8, lo[0].size), dtype=np.int64), np.empty((8, lo[0].size))
    for corner in range(8):
        b = [(corner >> k) & 1 for k in range(3)]
        weight[corner] = np.prod([f if bit else 1 - f for f, bit in zip(fr, b)], axis=0)
        index[corner] = ((lo[2] + b[2]) % N_PD) + N_PD * (lo[1] + b[1] + N_TD * (lo[0] + b[0]))
    return index, weight


def interpolate(brdf, where, interp="log"):
    """BRDF (3, n) of a (3, N_CELLS) array at the points of ``where = corners(wi, wo)``:
    ``linear``: trilinear over the neighbouring bin centres present (missing ones left out,
    weights renormalised), NaN where all are missing; ``log``: the same on log values (linear
    where a neighbour is <= 0).  Points whose corners are all present (and positive, for
    ``log``) take one gather and a weighted sum; the others the rule in full (`_interpolate`)."""
    if interp not in ("linear", "log"):
        raise ValueError(f"interp '{interp}': nearest, linear or log")
    index, weight = where
    brdf = np.asarray(brdf)
    if brdf.shape[1] > index.size:          # a whole table at a few points: only the cells they use
        used = np.unique(index)
        brdf, index = brdf[:, used], np.searchsorted(used, index)
    with np.errstate(invalid="ignore"):
        clean = brdf > 0 if interp == "log" else np.isfinite(brdf)
    flagged = ~np.logical_and.reduce(list(clean))       # not all(0): slow over a short first axis
    rough = np.flatnonzero(flagged[index].any(0)) if flagged.any() else np.zeros(0, np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        table = np.log(np.where(clean, brdf, 1.0)) if interp == "log" else np.where(clean, brdf, 0.0)
    out = np.einsum("ckn,kn->cn", np.take(table, index, axis=1), weight) / weight.sum(0)
    if interp == "log":
        out = np.exp(out)
    if rough.size:
        out[:, rough] = _interpolate(brdf, index[:, rough], weight[:, rough], interp)
    return out


def _interpolate(brdf, index, weight, interp):
    """`interpolate`'s rule at every point: missing corners left out, weights renormalised."""
    v = np.take(brdf, index, axis=1)             # (C, 8, n): one gather for every corner
    ok = np.isfinite(v)
    w_ok = np.where(ok, weight, 0.0)
    wsum = w_ok.sum(1)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        out = np.where(wsum > 0, np.einsum("ckn,ckn->cn", np.where(ok, v, 0.0), w_ok) / wsum, np.nan)
        if interp == "log":
            positive = ~np.any(ok & (v <= 0) & (weight != 0), axis=1)
            log_v = np.log(np.where(v > 0, v, 1.0))
            mean_log = np.einsum("ckn,ckn->cn", log_v, w_ok) / wsum
            out = np.where(positive & (wsum > 0), np.exp(mean_log), out)
    return out


def table_lookup(brdf, wi, wo, interp="log"):
    """BRDF (3, n) of a MerlTable or (3, N_CELLS) array at direction pairs (n, 3).

    ``nearest``: the value of the bin holding each pair, NaN where it is missing; ``linear`` and
    ``log``: `interpolate` between bin centres.  Log values interpolate a sharp peak as the shape
    it has (on the demo mirror, alpha = 1e-3, the environment sphere of the table is within 4 % of
    the model's, against 15 % interpolating linearly)."""
    brdf = brdf.brdf() if isinstance(brdf, MerlTable) else brdf
    if interp == "nearest":
        return brdf[:, nearest_cells(wi, wo)]
    return interpolate(brdf, corners(wi, wo), interp)
