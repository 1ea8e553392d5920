"""Cell sets: the geometry of the fitted cells and every material's measured values there, on the
device.

A batch of measurements (brdfcl.data.measurement) that share one layout (MERL tables) shares
one geometry, uploaded once (``geo_stride`` 0); otherwise (scattered samples) each material
brings its own, padded to the longest.  Data are (material, channel, cell), NaN where missing,
padded to a multiple of the vector width and split into blocks under the device's largest
allocation.  On a CPU device a block brdfcl owns (its own padded copy, or data read for the
pipeline: ``own``) is the buffer's memory (USE_HOST_PTR, no copy) and is made read-only.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyopencl as cl

from brdfcl.data.geometry import DEFAULT_CUTOFF_DEG, TABLE
from brdfcl.data.measurement import Layout, Measurement
from brdfcl.device.platforms import is_cpu
from brdfcl.model.lobes.cells import Cells

_CPUS = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
READ_WORKERS = min(4, _CPUS)     # threads reading measurement files: the CPUs this process may use
ALIGN = 128                      # bytes: the widest vector a kernel loads (double16)


def aligned_empty(shape, dtype) -> np.ndarray:
    """An uninitialised array whose data start on an ALIGN-byte boundary (a CPU device may then
    use it as a buffer's memory: the kernels' vector loads assume aligned rows)."""
    dtype = np.dtype(dtype)
    raw = np.empty(int(np.prod(shape)) * dtype.itemsize + ALIGN, dtype=np.uint8)
    start = -raw.ctypes.data % ALIGN
    return raw[start:start + int(np.prod(shape)) * dtype.itemsize].view(dtype).reshape(shape)


@dataclass(frozen=True)
class Place:
    """Where a material's cells are: its layout and the indices of the cells (in the layout's
    order), each with a weight scale (a coarse subset's stride; 1: none)."""

    layout: Layout
    index: np.ndarray
    scale: np.ndarray | float = 1.0

    def weights(self, cutoff_deg: float | None) -> np.ndarray:
        return self.layout.weights(self.index, cutoff_deg) * self.scale


@dataclass
class CellSet:
    """Selected cells of a batch of materials, on one device.

    Geometry rows: sin th, cos th, cos td, cos ti, cos to, weight, for all materials at once
    (``places`` of one entry, ``geo_stride`` 0) or one per material (``geom_host`` (n_mat, 6, n)).
    Data: (material, channel, cell), NaN where a cell is missing.  Padded to a multiple of the
    vector width with harmless cells at weight 0."""

    names: list
    index: np.ndarray                 # the shared cells' indices; per material: positions 0 .. longest-1
    n_cells: int                      # padded length
    dtype: type
    geom_host: np.ndarray
    blocks: list = field(default_factory=list)   # [(first material, count, data buffer)]
    geom_buf: Any = None              # cl.Buffer of geom_host
    places: list = field(default_factory=list)   # [Place] shared (one) or per material
    cutoff_deg: float | None = DEFAULT_CUTOFF_DEG
    targets: dict = field(default_factory=dict)  # (metric, cosw) -> per block, buffer of g(m cw)
    n_channels: int = 3
    _cells: dict = field(default_factory=dict)

    @property
    def shared(self) -> bool:
        return len(self.places) <= 1

    @property
    def geo_stride(self) -> int:
        """Offset between materials' geometries in the buffer (0: shared)."""
        return 0 if self.shared else 6 * self.n_cells

    @property
    def n_materials(self):
        return len(self.names)

    def place(self, mat: int = 0) -> Place:
        return self.places[0 if self.shared else mat]

    def cells(self, mat: int = 0) -> Cells:
        """float64 reference cells of a material (unpadded; the same for all when shared)."""
        key = 0 if self.shared else mat
        if key not in self._cells:
            p = self.place(mat)
            self._cells[key] = Cells(*p.layout.rows(p.index))
        return self._cells[key]

    def weights(self, mat: int = 0) -> np.ndarray:
        """float64 weights of a material's cells (unpadded), coarse scale included."""
        return self.place(mat).weights(self.cutoff_deg)

    def block_of(self, mat):
        for b, (first, count, _) in enumerate(self.blocks):
            if first <= mat < first + count:
                return b
        raise IndexError(mat)


def select_cells(cutoff_deg=DEFAULT_CUTOFF_DEG, stride=1, offset=0):
    """Table indices of the fitted cells of a MERL table: above the horizon, inside the cut-off,
    every stride-th."""
    idx = TABLE.select(cutoff_deg)
    return idx[offset::stride] if stride > 1 else idx


def read_values(measurements: Sequence[Measurement], indices: Callable[[int], Sequence[np.ndarray]],
                dtype=np.float32, on_error: Callable[[Measurement, Exception], None] | None = None,
                workers: int = READ_WORKERS, into: Callable[[int], list[np.ndarray]] | None = None,
                ) -> tuple[list[int], list[list[np.ndarray]]]:
    """Each measurement's values at each of its index sets (``indices(k)`` for measurement k):
    (the positions of those read, [[(C, n_i) per index set] per one read]).  Files are read by
    ``workers`` threads (reading and gathering release the GIL, so the cores read in parallel).
    One that raises is told to ``on_error(measurement, exc)`` and left out (re-raised if None).
    ``into(k)``: the arrays measurement k's values are written to (rows of a batch's stacked
    arrays, which then need no copy)."""
    def one(k):
        m = measurements[k]
        try:
            outs = into(k) if into is not None else \
                [np.empty((m.n_channels, np.size(i)), dtype) for i in indices(k)]
            m.values_at(indices(k), outs)
            return outs, None
        except Exception as e:
            return None, e

    kept, values = [], []
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        for k, (outs, err) in enumerate(pool.map(one, range(len(measurements)))):
            if err is not None:
                if on_error is None:
                    raise err
                on_error(measurements[k], err)
                continue
            kept.append(k)
            values.append(outs)
    return kept, values


def extract(tables, indices, dtype=np.float32, on_error=None, workers=READ_WORKERS):
    """The values of measurements sharing one layout (MERL tables) at each index set:
    (names, [(n_mat, C, n_i)]); one that cannot be read is told to ``on_error`` and left out."""
    items = list(tables)
    kept, stacked = read_stacked(items, indices, dtype, on_error, workers)
    return [items[k].name for k in kept], stacked


def read_stacked(measurements: Sequence[Measurement], indices: Sequence[np.ndarray], dtype=np.float32,
                 on_error=None, workers=READ_WORKERS) -> tuple[list[int], list[np.ndarray]]:
    """`read_values` for measurements sharing one layout, each read straight into its row of one
    array per index set: (the positions of those read, [(n_read, C, n_i)])."""
    n_ch = measurements[0].n_channels if measurements else 3
    stacked = [aligned_empty((len(measurements), n_ch, np.size(i)), dtype) for i in indices]
    kept, _ = read_values(measurements, lambda k: indices, dtype, on_error, workers,
                          into=lambda k: [s[k] for s in stacked])
    if len(kept) < len(measurements):
        stacked = [s[kept] for s in stacked]
    return kept, stacked


def _pad(n: int, pad_to: int) -> int:
    return max(pad_to, -(-n // pad_to) * pad_to)


def _rows(place: Place, cutoff_deg, n_pad: int) -> np.ndarray:
    """(6, n_pad) float64 geometry rows of a place, padded with copies of its first cell at weight 0."""
    n = place.index.size
    rows = np.empty((6, n_pad))
    if n:
        rows[:5, :n] = np.stack(place.layout.rows(place.index))
        rows[5, :n] = place.weights(cutoff_deg)
        rows[:, n:] = rows[:, :1]
    else:
        rows[:5] = 0.5
    rows[5, n:] = 0
    return rows


def build_cellset(ctx, names, places: Sequence[Place], data, dtype=np.float32, pad_to=16,
                  cutoff_deg=DEFAULT_CUTOFF_DEG, max_alloc=None, own=False):
    """Upload a batch: ``places`` one shared Place, or one per material; ``data`` (n_mat, C, n)
    for a shared place, else a list of (C, n_i) per material.  ``own``: ``data`` is the cell
    set's to keep (a CPU device then reads it in place, and it becomes read-only)."""
    places = list(places)
    if len(places) <= 1:
        place = places[0]
        n = place.index.size
        n_pad = _pad(n, pad_to)
        geom = _rows(place, cutoff_deg, n_pad).astype(dtype)
        index = place.index
        if not isinstance(data, np.ndarray):                # one material's (C, n) in a list
            data = np.stack(list(data))
        blocks = _data_blocks(ctx, data, n, n_pad, dtype, max_alloc, own)
        n_ch = data.shape[1]
    else:
        n_ch = {v.shape[0] for v in data}
        if len(n_ch) > 1:
            raise ValueError(f"materials with {sorted(n_ch)} channels cannot share one cell set")
        n_ch = n_ch.pop()
        longest = max(p.index.size for p in places)
        n_pad = _pad(longest, pad_to)
        geom = np.stack([_rows(p, cutoff_deg, n_pad) for p in places]).astype(dtype)
        padded = np.full((len(places), n_ch, n_pad), np.nan)
        for m, v in enumerate(data):
            padded[m, :, :v.shape[1]] = v
        index = np.arange(longest)
        blocks = _data_blocks(ctx, padded, n_pad, n_pad, dtype, max_alloc)
    geom_buf = cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=geom)
    return CellSet(list(names), index, n_pad, dtype, geom, blocks, geom_buf, places, cutoff_deg, n_channels=n_ch)


def _data_blocks(ctx, data, n, n_pad, dtype, max_alloc=None, own=False):
    """Per-material data (n_mat, C, n) padded to n_pad with NaN, in buffers under the device's
    largest allocation: [(first material, count, buffer)].  On a CPU device a block that is
    brdfcl's (a padded copy made here, or slices of ``data`` when ``own``) and aligned is the
    buffer's memory; it is made read-only, since the buffer reads it in place."""
    n_ch = data.shape[1]
    per_mat = n_ch * n_pad * np.dtype(dtype).itemsize
    max_alloc = max_alloc or ctx.devices[0].max_mem_alloc_size
    per_block = max(1, int(max_alloc // per_mat))
    in_place = is_cpu(ctx.devices[0])
    mf = cl.mem_flags
    blocks = []
    for first in range(0, len(data), per_block):
        if n == n_pad and data.dtype == dtype and data.flags.c_contiguous:
            chunk = data[first:first + per_block]            # no padding needed: no copy
            mine = own
        else:
            chunk = aligned_empty((min(per_block, len(data) - first), n_ch, n_pad), dtype)
            chunk[:, :, n:] = np.nan
            chunk[:, :, :n] = data[first:first + per_block]
            mine = True
        if in_place and mine and chunk.ctypes.data % ALIGN == 0:
            for a in (chunk, data) if own else (chunk,):
                a.flags.writeable = False
            flags = mf.READ_ONLY | mf.USE_HOST_PTR
        else:
            flags = mf.READ_ONLY | mf.COPY_HOST_PTR
        blocks.append((first, len(chunk), cl.Buffer(ctx, flags, hostbuf=chunk)))
    return blocks
