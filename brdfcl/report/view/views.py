"""Every direction pair the report shows of a material, planned once per process.

A report page shows lit spheres (brdfcl.report.view.sphere's camera and lights) and slices
(brdfcl.report.view.slices) of the measurement and of its fit.  Their geometry is the same for
every material, so a `Plan` computes it once: the direction pairs of the point-lit sphere pixels
and of the slices (``cells``, with the table's interpolation corners there), and for each
environment-lit sphere a sparse operator from table cells to pixels (``EnvView``).  Each
material then costs a table interpolation, one model evaluation at the plan's points (the
OpenCL engine for all materials of one model at once, brdfcl.report.view.evaluate) and three
sparse products per environment sphere.

The environment sphere integrates, per pixel, one fixed set of half vectors
(sphere.half_vector_samples) as sphere.render_sphere does, with each sample taking the value of
the table cell whose bin holds it, for the measurement and for the fit alike (the fit is
evaluated at those cells' bin centres: the model tabulated as a MERL table; every theta_h bin,
every second theta_d and phi_d bin).  Both images thus see the same discretisation, and their
difference is the model's, not the lookup's.  Near the horizon a bin's centre can lie far from
the sample in cos theta, where a model's 1 / cos(theta) is large: such samples are left out and
their weight spread over the pixel's others.  The image stays close to the exact rendering of a
fit (sphere.render_model_sphere; tests/test_view.py bounds the median relative difference): within
a percent for rough and medium lobes, several percent for mirror-like ones such as chrome, whose
peak is narrower than the table's first theta_h bins.  The operator is computed once per machine
(brdfcl._cache.generated_arrays).
"""
from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np

from brdfcl._cache import generated_arrays
from brdfcl.data.geometry import N_CELLS, table_geometry
from brdfcl.model.lobes.cells import Cells
from brdfcl.report.view import sphere
from brdfcl.report.view.lookup import corners, interpolate, nearest_cells
from brdfcl.report.view.slices import INCIDENCE_DEG, PLANES, outgoing_deg, slice_directions

ENV_STRIDE = (1, 2, 2)            # the environment's table: every theta_h bin, every 2nd theta_d and phi_d
GRAZING_LOG_RATIO = np.log(1.5)   # a sample whose bin centre's cos theta_i or _o is off by more: left out


@dataclass
class PointView:
    """A sphere under a point light: its pixels on the sphere (``inside``), the lit ones among them
    (``lit``) with their cos(theta_i), and where their direction pairs are in the plan (``span``)."""

    label: str
    light: np.ndarray
    size: int
    inside: np.ndarray
    lit: np.ndarray
    cos: np.ndarray
    span: slice
    kind = "point"

    def image(self, values):
        """Radiance (size, size, 3) from BRDF values (3, n) at the plan's points; NaN off the sphere."""
        out = np.full((self.size, self.size, 3), np.nan)
        rad = np.zeros((int(self.inside.sum()), 3))
        rad[self.lit] = (values[:, self.span] * self.cos).T
        out[self.inside] = rad
        return out


@dataclass
class EnvView:
    """A sphere in the sky/ground environment: per channel a sparse (pixels x cells) matrix of
    sample weights times the environment's radiance, for the table cells ``cells`` (``operator``:
    its CSR arrays, `_env_arrays`; the matrices are made where an image is first drawn, so that a
    process that only evaluates a plan's cells needs no scipy.sparse)."""

    label: str
    light: np.ndarray
    size: int
    inside: np.ndarray
    cells: np.ndarray
    operator: dict
    kind = "env"
    columns: np.ndarray | None = None     # where ``cells`` are in the plan's env_cells; None: all of them, in order

    @cached_property
    def weights(self) -> tuple:
        """The three channels' matrices, in float32: an image needs no more, and a product reads
        less memory."""
        from scipy import sparse  # here: importing it costs a start-up 0.1-0.2 s
        a = self.operator
        shape = (int(self.inside.sum()), self.cells.size)
        data = np.ascontiguousarray(a["data"].T, dtype=np.float32)
        return tuple(sparse.csr_matrix((data[c], a["indices"], a["indptr"]), shape=shape) for c in range(3))

    @cached_property
    def total(self) -> list:
        return [np.maximum(np.asarray(w.sum(axis=1)).ravel(), 1e-300) for w in self.weights]

    def image(self, at_env):
        """Radiance (size, size, 3) from BRDF values at the plan's ``env_cells`` (3, m); NaN off
        the sphere and where less than sphere.MIN_VALID_SHARE of the light meets a value."""
        values = np.asarray(at_env if self.columns is None else at_env[:, self.columns], dtype=np.float32)
        out = np.full((self.size, self.size, 3), np.nan)
        good = np.isfinite(values)
        rad = np.empty((int(self.inside.sum()), 3))
        for c, w in enumerate(self.weights):
            if good[c].all():
                rad[:, c] = w @ values[c]
                continue
            share = (w @ good[c].astype(np.float32)) / self.total[c]
            r = (w @ np.where(good[c], values[c], 0.0).astype(np.float32)) / np.maximum(share, 1e-300)
            rad[:, c] = np.where(share >= sphere.MIN_VALID_SHARE, r, np.nan)
        out[self.inside] = rad
        return out


@dataclass
class SliceView:
    """One slice: the outgoing angles (deg), their cos(theta_o) and where they are in the plan."""

    dphi: float | None
    theta_i: float
    theta_o: np.ndarray
    cos: np.ndarray
    span: slice


class Plan:
    """The report's views (see the module's docstring): ``spheres`` (key, grazing, environment
    at the sizes given) and the ``slices``; ``cells``
    holds every point view's and slice's direction pairs in order, ``in_plane`` the span of the
    in-plane slices (where the lobes are drawn one by one); ``turntable`` the measured-only
    spheres (``turntable_size`` pixels) under a point light at each of ``turntable_deg`` from the
    view, at azimuth 0 (the page's live view turns them to its light's azimuth), each computed on
    its upper half and mirrored."""

    def __init__(self, lights, size, env_size, turntable_deg=(), turntable_size=64):
        wi_all, wo_all, spheres, n = [], [], [], 0
        views = [(label, kind, d, min(size, env_size) if kind == "env" else size) for label, kind, d in lights]
        for label, kind, d, s in views:
            if kind == "env":
                spheres.append(_env_view(label, d, s))
                continue
            view, wi, wo = _point_view(label, d, s, n)
            spheres.append(view)
            wi_all.append(wi)
            wo_all.append(wo)
            n += len(wi)
        self.spheres = spheres
        self.slices = []
        first = n
        for dphi, _ in PLANES:
            for ti in INCIDENCE_DEG:
                to = outgoing_deg(dphi)
                wi, wo = slice_directions(ti, to, dphi)
                self.slices.append(SliceView(dphi, ti, to, wo[:, 2], slice(n, n + len(to))))
                wi_all.append(wi)
                wo_all.append(wo)
                n += len(to)
            if dphi is None:
                self.in_plane = slice(first, n)
        wi, wo = np.concatenate(wi_all), np.concatenate(wo_all)
        self.cells = Cells.from_directions(wi, wo)
        self.corners = corners(wi, wo)
        envs = [v for v in self.spheres if isinstance(v, EnvView)]
        self.env_cells = _unique_cells([v.cells for v in envs])
        for v in envs:
            same = v.cells.size == self.env_cells.size and np.array_equal(v.cells, self.env_cells)
            v.columns = None if same else np.searchsorted(self.env_cells, v.cells)
        self.turntable, wi_t, wo_t, m = [], [], [], 0
        for deg in turntable_deg:
            t = np.radians(deg)
            view, wi, wo = _upper_half_view(f"{deg:g}", np.array([np.sin(t), 0.0, np.cos(t)]), turntable_size, m)
            self.turntable.append(view)
            wi_t.append(wi)
            wo_t.append(wo)
            m += len(wi)
        turn = corners(np.concatenate(wi_t), np.concatenate(wo_t)) if m else (np.zeros((8, 0), np.int64),) * 2
        self.table_cells = _unique_cells([self.corners[0], self.env_cells, turn[0]])
        """Every table cell a view reads: a report gathers only these of each table."""
        self._corners_at = _compact(np.searchsorted(self.table_cells, self.corners[0]), self.corners[1])
        self._env_at = np.searchsorted(self.table_cells, self.env_cells)
        self._turn_at = _compact(np.searchsorted(self.table_cells, turn[0]), turn[1])

    def table_values(self, table):
        """A table's BRDF (3, len(table_cells)) at ``table_cells``: ``table`` a MerlTable or a
        (3, N_CELLS) array."""
        if hasattr(table, "brdf_at"):
            return table.brdf_at(self.table_cells)
        return np.asarray(table, dtype=np.float64)[:, self.table_cells]

    def measured(self, values):
        """From a table's `table_values`: (3, n) at ``cells`` (log-trilinear,
        brdfcl.report.view.lookup) and (3, len(env_cells)) at ``env_cells``."""
        used, where = self._corners_at
        return interpolate(values[:, used], where), values[:, self._env_at]

    def turntable_images(self, values):
        """Radiance images of the measured-only turntable spheres from a table's `table_values`."""
        used, where = self._turn_at
        at = interpolate(values[:, used], where)
        return [v.image(at) for v in self.turntable]

    def images(self, at_points, at_env):
        """{label: radiance image} of every sphere, from values at ``cells`` and at ``env_cells``."""
        return {v.label: v.image(at_env if v.kind == "env" else at_points) for v in self.spheres}


def plan(lights=None, size=128, env_size=64, turntable_deg=(), turntable_size=64) -> Plan:
    """The Plan of these views (sphere.DEFAULT_LIGHTS' form), made once per process."""
    key = tuple((label, kind, tuple(float(x) for x in d)) for label, kind, d in lights or sphere.DEFAULT_LIGHTS)
    return _plan(key, size, env_size, tuple(float(a) for a in turntable_deg), turntable_size)


@lru_cache(maxsize=4)
def _plan(lights, size, env_size, turntable_deg, turntable_size):
    return Plan([(label, kind, np.array(d)) for label, kind, d in lights], size, env_size, turntable_deg,
                turntable_size)


@dataclass
class MirroredView(PointView):
    """A sphere under a light in the x-z plane, whose upper half (``lit``: pixels there) is
    computed and mirrored: the image is symmetric about y = 0 for an isotropic BRDF."""

    def image(self, values):
        out = super().image(values)
        half = self.size // 2
        out[self.size - half:] = out[:half][::-1]
        return out


def _upper_half_view(label, light, size, first):
    """`_point_view` of a light in the x-z plane and an even ``size``: its pixels in the upper half."""
    assert light[1] == 0 and size % 2 == 0, "a mirrored view needs a light in the x-z plane and an even size"
    view, wi, wo = _point_view(label, light, size, first)
    top = view.lit < int(view.inside.sum()) // 2          # the inside pixels in order: the upper rows first
    lit, cos = view.lit[top], view.cos[top]
    return (MirroredView(label, view.light, size, view.inside, lit, cos, slice(first, first + lit.size)),
            wi[top], wo[top])


def _point_view(label, light, size, first):
    light = sphere._unit(*light)
    inside, n, t, b, wo = sphere.pixel_frames(size)
    lit, cos, wi = sphere.point_samples(n, t, b, light)
    return PointView(label, light, size, inside, lit, cos, slice(first, first + lit.size)), wi, wo[lit]


def _compact(index, weight):
    """Interpolation corners (`lookup.corners`) at positions ``index`` of the plan's table cells
    as (the positions they use, the corners at those): a lookup then reads (and takes the log of)
    only the cells it needs."""
    used = _unique_cells([index], index.max() + 1 if index.size else 0)
    return used, (np.searchsorted(used, index), weight)


def _unique_cells(parts, n=N_CELLS) -> np.ndarray:
    """The sorted distinct table cells of ``parts`` (int arrays of any shape): np.unique's result,
    by a mark per table cell (a tenth of its time for the plan's million indices)."""
    seen = np.zeros(n, dtype=bool)
    for part in parts:
        seen[np.asarray(part, dtype=np.int64).ravel()] = True
    return np.flatnonzero(seen)


def _env_view(label, zenith, size):
    zenith = sphere._unit(*zenith)
    inside = sphere.sphere_normals(size)[1]
    key = hashlib.sha1(repr((_sources(), tuple(zenith), size, ENV_STRIDE, GRAZING_LOG_RATIO,
                             sphere.half_vector_samples()[0].shape)).encode()).hexdigest()[:24]
    a = generated_arrays("report-env", key, lambda: _env_arrays(zenith, size))
    return EnvView(label, zenith, size, inside, a["cells"], a)


def _sources():
    """What the environment operator is computed from: these modules' text."""
    from brdfcl.data import geometry
    from brdfcl.report.view import lookup
    return hashlib.sha1(b"".join(Path(m.__file__).read_bytes()
                                 for m in (sys.modules[__name__], sphere, lookup, geometry))).hexdigest()


def _env_arrays(zenith, size):
    """The environment operator as arrays: its table ``cells`` and one CSR pattern (``indptr``,
    ``indices``) with the weights of the three channels (``data``, (nnz, 3))."""
    from scipy import sparse
    inside, n, t, b, wo = sphere.pixel_frames(size)
    pix, wi, weight = sphere.env_samples(n, t, b, wo, zenith)
    cell = nearest_cells(wi, wo[pix], ENV_STRIDE)
    g = table_geometry()
    # near the horizon a bin's centre may lie far from the sample in cos theta (and the model's
    # 1 / cos there): such samples, and bins below the horizon, are left out (the bins hold
    # direction pairs in either order: reciprocity)
    lo, hi = np.minimum(wi[:, 2], wo[pix, 2]), np.maximum(wi[:, 2], wo[pix, 2])
    c_lo, c_hi = np.minimum(g.cos_i[cell], g.cos_o[cell]), np.maximum(g.cos_i[cell], g.cos_o[cell])
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.maximum(np.abs(np.log(c_lo / lo)), np.abs(np.log(c_hi / hi)))
    keep = g.above_horizon[cell] & (off < GRAZING_LOG_RATIO)
    full = np.bincount(pix, weight.sum(1), minlength=n.shape[0])
    kept = np.bincount(pix[keep], weight[keep].sum(1), minlength=n.shape[0])
    weight *= (full / np.maximum(kept, 1e-300))[pix, None]          # what is left out, spread over the rest
    pix, cell, weight = pix[keep], cell[keep], weight[keep]
    cells, col = np.unique(cell, return_inverse=True)
    shape = (int(inside.sum()), cells.size)
    pattern = sparse.csr_matrix((np.arange(1, pix.size + 1, dtype=float), (pix, col)), shape=shape)
    pattern.sum_duplicates()
    per_channel = [sparse.csr_matrix((weight[:, c], (pix, col)), shape=shape) for c in range(3)]
    assert all(np.array_equal(m.indices, pattern.indices) for m in per_channel)
    data = np.stack([m.data for m in per_channel], -1)
    return {"cells": cells, "indptr": pattern.indptr, "indices": pattern.indices, "data": data}
