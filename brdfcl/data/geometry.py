"""Geometry of the MERL table, computed once (docs/spec.md section 2), and its layout.

Models are evaluated at bin centres in index space.  Each cell carries the
solid-angle measure of its bin, integrated exactly over the bin:
``dwi dwo = 4 cos td sin th sin td dth dph dtd dpd``, with phi_h over 2 pi and
phi_d over [0, 2 pi) folded onto [0, pi) by reciprocity (a factor 2).  The
valid cells then sum to the measure of the pairs of upper hemispheres,
(2 pi)^2, up to the error of masking whole cells at the horizon.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from brdfcl.data.measurement import Layout, Measurement

N_TH, N_TD, N_PD = 90, 90, 180
"""The MERL table's bins: theta_h (square-root spaced), theta_d, phi_d (folded onto [0, pi))."""
N_CELLS = N_TH * N_TD * N_PD

DEFAULT_CUTOFF_DEG = 80.0
"""Default angle cut-off: cells with theta_i or theta_o beyond it are left out
of fits (MERL is noisy near grazing; the proxy is unreliable there)."""


def bin_centres():
    """theta_h, theta_d, phi_d at the bin centres in index space (radians)."""
    th = 0.5 * np.pi * ((np.arange(N_TH) + 0.5) / N_TH) ** 2
    td = 0.5 * np.pi * (np.arange(N_TD) + 0.5) / N_TD
    pd = np.pi * (np.arange(N_PD) + 0.5) / N_PD
    return th, td, pd


def bin_weights():
    """Per-axis exact integrals of the measure over each bin (th, td, pd factors)."""
    th_edges = 0.5 * np.pi * (np.arange(N_TH + 1) / N_TH) ** 2
    td_edges = 0.5 * np.pi * np.arange(N_TD + 1) / N_TD
    w_th = np.cos(th_edges[:-1]) - np.cos(th_edges[1:])            # int sin th dth
    s2 = np.sin(td_edges) ** 2
    w_td = 2.0 * (s2[1:] - s2[:-1])                                   # int 4 cos td sin td dtd
    w_pd = np.full(N_PD, 2.0 * np.pi / N_PD)                          # int dpd, folded x2
    return w_th * 2.0 * np.pi, w_td, w_pd                             # phi_h over 2 pi


@dataclass(frozen=True)
class Geometry:
    """Per-cell geometry of the full table, flattened in MERL cell order."""

    theta_h: np.ndarray
    theta_d: np.ndarray
    phi_d: np.ndarray
    wi: np.ndarray            # (N_CELLS, 3)
    wo: np.ndarray            # (N_CELLS, 3)
    weight: np.ndarray        # solid-angle measure of each cell (sr^2)

    @property
    def cos_i(self):
        return self.wi[:, 2]

    @property
    def cos_o(self):
        return self.wo[:, 2]

    @property
    def above_horizon(self):
        return (self.cos_i > 0) & (self.cos_o > 0)

    def mask(self, cutoff_deg: float | None = DEFAULT_CUTOFF_DEG) -> np.ndarray:
        """Cells above the horizon with theta_i and theta_o below the cut-off (None: 90 deg)."""
        if cutoff_deg is None or cutoff_deg >= 90:
            return self.above_horizon
        if not 0 < cutoff_deg <= 90:
            raise ValueError(f"angle cut-off {cutoff_deg} deg: must be in (0, 90]")
        c = np.cos(np.radians(cutoff_deg))
        return (self.cos_i > c) & (self.cos_o > c)


def directions(theta_h, theta_d, phi_d):
    """(wi, wo) unit vectors from Rusinkiewicz angles with phi_h = 0."""
    st, ct = np.sin(theta_h), np.cos(theta_h)
    d = np.stack([np.sin(theta_d) * np.cos(phi_d),
                  np.sin(theta_d) * np.sin(phi_d),
                  np.cos(theta_d)], axis=-1)
    wi = np.stack([d[..., 0] * ct + d[..., 2] * st,                   # Ry(theta_h) d
                   d[..., 1],
                   -d[..., 0] * st + d[..., 2] * ct], axis=-1)
    h = np.stack([st, np.zeros_like(st), ct], axis=-1)
    wo = 2.0 * np.sum(wi * h, axis=-1, keepdims=True) * h - wi
    return wi, wo


def grid_directions(theta_h, theta_d, phi_d):
    """`directions` on the grid theta_h x theta_d x phi_d (1-D axes), flattened in that order: the
    same values, with the sines and cosines taken on the axes only (8x faster for the table)."""
    st, ct = np.sin(theta_h)[:, None, None], np.cos(theta_h)[:, None, None]
    sd, cd = np.sin(theta_d)[None, :, None], np.cos(theta_d)[None, :, None]
    dx, dy = sd * np.cos(phi_d)[None, None, :], sd * np.sin(phi_d)[None, None, :]
    shape = (len(theta_h), len(theta_d), len(phi_d), 3)
    wi, wo = np.empty(shape), np.empty(shape)
    wi[..., 0] = dx * ct + cd * st
    wi[..., 1] = dy
    wi[..., 2] = -dx * st + cd * ct
    dot = wi[..., 0] * st + wi[..., 2] * ct                            # wi . h, h = (st, 0, ct)
    wo[..., 0] = 2.0 * dot * st - wi[..., 0]
    wo[..., 1] = -wi[..., 1]
    wo[..., 2] = 2.0 * dot * ct - wi[..., 2]
    return wi.reshape(-1, 3), wo.reshape(-1, 3)


def rusinkiewicz(wi, wo):
    """(theta_h, theta_d, phi_d in [0, pi)) of direction pairs (n = z): the inverse of
    brdfcl.data.geometry.directions, phi_d folded by reciprocity as MERL does."""
    h = wi + wo
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    th = np.arccos(np.clip(h[..., 2], -1.0, 1.0))
    ph = np.arctan2(h[..., 1], h[..., 0])
    x = wi[..., 0] * np.cos(ph) + wi[..., 1] * np.sin(ph)          # Rz(-phi_h) wi
    y = -wi[..., 0] * np.sin(ph) + wi[..., 1] * np.cos(ph)
    st, ct = np.sin(th), np.cos(th)
    dx, dz = x * ct - wi[..., 2] * st, x * st + wi[..., 2] * ct        # Ry(-theta_h)
    return th, np.arccos(np.clip(dz, -1.0, 1.0)), np.mod(np.arctan2(y, dx), np.pi)


def index_coordinates(wi, wo):
    """Fractional (theta_h, theta_d, phi_d) bin coordinates of direction pairs (those of
    brdfcl.data.geometry.bin_centres: theta_h's is 90 sqrt(theta_h / (pi/2)) - 1/2)."""
    th, td, pd = rusinkiewicz(np.asarray(wi, float), np.asarray(wo, float))
    _, td0, pd0 = bin_centres()
    return [np.clip(N_TH * np.sqrt(th / (np.pi / 2)) - 0.5, 0, N_TH - 1),
            np.clip(td / (td0[1] - td0[0]) - 0.5, 0, N_TD - 1), pd / (pd0[1] - pd0[0]) - 0.5]


def nearest_cells(wi, wo, stride=(1, 1, 1)):
    """The table cell index (n,) whose bin holds each direction pair; with ``stride`` (theta_h,
    theta_d, phi_d) the nearest of every stride-th bin along each axis (a coarser table)."""
    u = index_coordinates(wi, wo)
    i = [np.floor(x / s + 0.5).astype(int) * s for x, s in zip(u, stride)]
    i[0], i[1] = (np.clip(x, 0, (n - 1) // s * s) for x, n, s in zip(i[:2], (N_TH, N_TD), stride))
    return (i[2] % N_PD) + N_PD * (i[1] + N_TD * i[0])


@lru_cache(maxsize=1)
def table_geometry() -> Geometry:
    """The geometry of the whole 90 x 90 x 180 table (computed once per process)."""
    th, td, pd = bin_centres()
    TH, TD, PD = (a.ravel() for a in np.meshgrid(th, td, pd, indexing="ij"))
    wi, wo = grid_directions(th, td, pd)
    w_th, w_td, w_pd = bin_weights()
    weight = (w_th[:, None, None] * w_td[None, :, None] * w_pd[None, None, :]).ravel()
    for a in (TH, TD, PD, wi, wo, weight):
        a.setflags(write=False)
    assert weight.size == N_CELLS
    return Geometry(TH, TD, PD, wi, wo, weight)


def cells_geometry(index) -> Geometry:
    """The geometry of the table cells ``index`` alone (as ``table_geometry()`` holds them there,
    up to rounding), for a few cells without the whole table's 1.5 million."""
    index = np.asarray(index)
    i_th, rest = np.divmod(index, N_TD * N_PD)
    i_td, i_pd = np.divmod(rest, N_PD)
    th, td, pd = bin_centres()
    wi, wo = directions(th[i_th], td[i_td], pd[i_pd])
    w_th, w_td, w_pd = bin_weights()
    return Geometry(th[i_th], td[i_td], pd[i_pd], wi, wo, w_th[i_th] * w_td[i_td] * w_pd[i_pd])


class TableLayout(Layout):
    """The cells of the MERL table (90 x 90 x 180 Rusinkiewicz bins, in MERL cell order), each at
    its bin centre with its bin's exact measure (`table_geometry`): one object every MERL table
    shares."""

    dense = True

    @staticmethod
    @lru_cache(maxsize=4)
    def _selected(cutoff_deg: float | None) -> np.ndarray:
        index = np.flatnonzero(table_geometry().mask(cutoff_deg))
        index.setflags(write=False)
        return index

    def select(self, cutoff_deg: float | None = DEFAULT_CUTOFF_DEG) -> np.ndarray:
        return self._selected(cutoff_deg)

    def weights(self, index: np.ndarray, cutoff_deg: float | None = DEFAULT_CUTOFF_DEG) -> np.ndarray:
        return table_geometry().weight[index]

    def rows(self, index: np.ndarray) -> tuple[np.ndarray, ...]:
        g = table_geometry()
        th = g.theta_h[index]
        return np.sin(th), np.cos(th), np.cos(g.theta_d[index]), g.cos_i[index], g.cos_o[index]

    def lookup(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        ok = (wi[..., 2] > 0) & (wo[..., 2] > 0)
        return np.where(ok, nearest_cells(wi, wo), -1)

    def coarse(self, index: np.ndarray, stride: int, peak_bins: int,
               peak_stride: int) -> tuple[np.ndarray, np.ndarray]:
        """Denser near the specular peak, where sharp lobes live in few theta_h bins: every
        ``peak_stride``-th cell of the first ``peak_bins`` theta_h bins, every ``stride``-th of the
        rest."""
        return coarse_cells(index, stride, peak_bins, peak_stride)


TABLE = TableLayout()
"""The MERL table's layout."""


def table_values(m: Measurement, index: np.ndarray) -> np.ndarray:
    """A measurement's BRDF (C, len(index)) float64 at the MERL table's cells ``index``, NaN where
    missing: a MERL table's own cells; another table's nearest cell to each bin centre (its
    layout's `lookup`), what the analysis and the report read of any table.  ValueError for a
    measurement whose layout has no lookup (scattered samples)."""
    index = np.asarray(index)
    out = np.full((m.n_channels, index.size), np.nan)
    if m.layout is TABLE:
        m.values_at([index], [out])
        return out
    g = table_geometry()
    cells = m.layout.lookup(g.wi[index], g.wo[index])
    if cells is None:
        raise ValueError(f"{m.path or m.name}: not a table: its samples have no cells to look up")
    found = cells >= 0
    got = np.empty((m.n_channels, int(found.sum())))
    m.values_at([cells[found]], [got])
    out[:, found] = got
    return out


def coarse_cells(full_index: np.ndarray, stride: int, peak_bins: int, peak_stride: int,
                 theta_h: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A coarse subset of the cells ``full_index`` for the global search: (indices, weight
    scales).  Denser near the specular peak, where sharp lobes live in few theta_h bins: every
    ``peak_stride``-th cell of the MERL table's first ``peak_bins`` theta_h bins (of any table:
    ``theta_h``, each cell's, below those bins' upper edge), every ``stride``-th of the rest; the
    weights are scaled by the strides so that its loss estimates the full one."""
    if theta_h is None:
        peak = full_index // (N_TD * N_PD) < peak_bins
    else:
        peak = theta_h < 0.5 * np.pi * (peak_bins / N_TH) ** 2
    near = np.flatnonzero(peak)[::peak_stride]
    rest = np.flatnonzero(~peak)[::stride]
    idx = np.concatenate([near, rest])
    scale = np.concatenate([np.full(near.size, float(peak_stride)), np.full(rest.size, float(stride))])
    order = np.argsort(idx)
    return full_index[idx[order]], scale[order]
