"""Cell sets: the geometry of the fitted cells and every material's measured values there, on the
device.

MERL tables share one geometry (a selection of table cells, computed once); scattered samples
bring one per material.  Data are (material, channel, cell), NaN where missing, padded to a
multiple of the vector width and split into blocks under the device's largest allocation.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyopencl as cl

from brdfcl.data.geometry import DEFAULT_CUTOFF_DEG, table_geometry
from brdfcl.data.merl import N_CELLS
from brdfcl.model.lobes.cells import Cells

_CPUS = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
READ_WORKERS = min(4, _CPUS)     # threads reading MERL files (extract): the CPUs this process may use


@dataclass
class CellSet:
    """Selected cells of the table for a list of materials, on one device.

    Geometry rows: sin th, cos th, cos td, cos ti, cos to, weight: one geometry for all
    materials (MERL tables, ``geo_stride`` 0) or one per material (scattered samples,
    ``geom_host`` (n_mat, 6, n)).  Data: (material, channel, cell), NaN where a cell is missing.  Padded to a multiple
    of the vector width with copies of the first cell at weight 0."""

    names: list
    index: np.ndarray                 # table cell index of each (unpadded) cell
    n_cells: int                      # padded length
    dtype: type
    geom_host: np.ndarray
    blocks: list = field(default_factory=list)   # [(first material, count, data buffer)]
    geom_buf: Any = None              # cl.Buffer of geom_host
    per_material: list | None = None  # scattered samples: each material's float64 Cells
    targets: dict = field(default_factory=dict)  # (metric, cosw) -> per block, buffer of g(m cw)

    @property
    def geo_stride(self) -> int:
        """Offset between materials' geometries in the buffer (0: shared)."""
        return 0 if self.per_material is None else 6 * self.n_cells

    n_channels: int = 3

    @property
    def n_materials(self):
        return len(self.names)

    def cells(self, mat: int = 0) -> Cells:
        """float64 reference cells of this set (unpadded; of material ``mat`` for scattered data)."""
        if self.per_material is not None:
            return self.per_material[mat]
        return Cells.from_geometry(table_geometry(), self.index)

    def block_of(self, mat):
        for b, (first, count, _) in enumerate(self.blocks):
            if first <= mat < first + count:
                return b
        raise IndexError(mat)


def select_cells(cutoff_deg=DEFAULT_CUTOFF_DEG, stride=1, offset=0):
    """Table indices of the fitted cells: above the horizon, inside the cut-off, every stride-th."""
    idx = np.flatnonzero(table_geometry().mask(cutoff_deg))
    return idx[offset::stride] if stride > 1 else idx


def extract(tables, indices, dtype=np.float32, on_error=None, workers=READ_WORKERS):
    """Read each table once and keep its values at each index set: (names, [(n_mat, C, n_i)]).

    ``tables`` yields MerlTable objects, callables returning one, or readers with a
    ``values_at(indices, outs, buffer)`` method (brdfcl.data.inputs.FileReader: the file's values go
    straight to the result, through one reusable read buffer per thread); files are read lazily,
    by ``workers`` threads (reading and subsetting a file release the GIL, so the cores read in
    parallel).  A table that raises is reported to ``on_error(item, exc)`` and skipped (re-raised if
    None)."""
    items = list(tables)
    out = [np.empty((len(items), 3, idx.size), dtype) for idx in indices]       # MERL: 3 channels
    local = threading.local()

    def one(k):
        item = items[k]
        try:
            if hasattr(item, "values_at"):
                if not hasattr(local, "buffer"):
                    local.buffer = np.empty(3 * N_CELLS)
                return item.values_at(indices, [o[k] for o in out], local.buffer), None
            t = item() if callable(item) else item
            for o, idx in zip(out, indices):
                t.brdf_at(idx, dtype, out=o[k])
            return t.name, None
        except Exception as e:
            return None, e

    names, kept = [], []
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        for k, (name, err) in enumerate(pool.map(one, range(len(items)))):
            if err is not None:
                if on_error is None:
                    raise err
                on_error(items[k], err)
                continue
            names.append(name)
            kept.append(k)
    if len(kept) == len(items):
        return names, out
    return names, [o[kept] for o in out]


def build_cellset(ctx, names, index, data, dtype=np.float32, pad_to=16, weight_scale=None,
                  max_alloc=None):
    """Upload geometry and per-material data (n_mat, C, n) for the given table cells."""
    g = table_geometry()
    n = index.size
    n_pad = max(pad_to, -(-n // pad_to) * pad_to)
    full = np.concatenate([index, np.full(n_pad - n, index[0] if n else 0)])
    geom = np.stack([np.sin(g.theta_h[full]), np.cos(g.theta_h[full]), np.cos(g.theta_d[full]),
                     g.cos_i[full], g.cos_o[full], g.weight[full]])
    if weight_scale is not None:
        geom[5, :n] *= weight_scale
    geom = geom.astype(dtype)
    geom[5, n:] = 0
    mf = cl.mem_flags
    geom_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=geom)
    blocks = _data_blocks(ctx, data, n, n_pad, dtype, max_alloc)
    return CellSet(list(names), index, n_pad, dtype, geom, blocks, geom_buf, n_channels=data.shape[1])


def _data_blocks(ctx, data, n, n_pad, dtype, max_alloc=None):
    """Per-material data (n_mat, C, n) padded to n_pad with NaN, in buffers under the device's
    largest allocation: [(first material, count, buffer)]."""
    n_ch = data.shape[1]
    per_mat = n_ch * n_pad * np.dtype(dtype).itemsize
    max_alloc = max_alloc or ctx.devices[0].max_mem_alloc_size
    per_block = max(1, int(max_alloc // per_mat))
    blocks = []
    for first in range(0, len(data), per_block):
        if n == n_pad and data.dtype == dtype and data.flags.c_contiguous:
            chunk = data[first:first + per_block]            # no padding needed: no copy
        else:
            chunk = np.full((min(per_block, len(data) - first), n_ch, n_pad), np.nan, dtype=dtype)
            chunk[:, :, :n] = data[first:first + per_block]
        blocks.append((first, len(chunk), cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                                                    hostbuf=chunk)))
    return blocks


def build_sample_cellset(ctx, names, cells, weights, values, dtype=np.float32, pad_to=16, max_alloc=None):
    """Upload scattered measurements: per material its Cells, weights (n_i,) and values (C, n_i),
    padded to the longest at weight 0 (materials may hold different sample counts)."""
    n_ch = {v.shape[0] for v in values}
    if len(n_ch) > 1:
        raise ValueError(f"materials with {sorted(n_ch)} channels cannot share one cell set")
    longest = max((len(c) for c in cells), default=0)
    n_pad = max(pad_to, -(-longest // pad_to) * pad_to)
    geom = np.zeros((len(cells), 6, n_pad))
    data = np.full((len(cells), n_ch.pop() if n_ch else 3, n_pad), np.nan)
    geom[:, :5] = 0.5                      # padding: a harmless cell (weight 0)
    for m, (c, w, v) in enumerate(zip(cells, weights, values)):
        k = len(c)
        geom[m, :, :k] = np.stack([c.sh, c.ch, c.cd, c.ci, c.co, w])
        data[m, :, :k] = v
    geom = geom.astype(dtype)
    geom_buf = cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=geom)
    blocks = _data_blocks(ctx, data, n_pad, n_pad, dtype, max_alloc)
    index = np.arange(longest)
    return CellSet(list(names), index, n_pad, dtype, geom, blocks, geom_buf, per_material=list(cells),
                   n_channels=data.shape[1])
