"""The OpenCL engine: a database's cells on the device, evaluated for many parameter vectors at once.

A `CellSet` (brdfcl.device.cellsets) is the geometry of the fitted cells and the measured
values of every material there, uploaded once.  An `Engine` is one compiled program for one
model; each call evaluates a batch of (material, parameter vector) pairs in one launch per
buffer block and returns float64 sums.  Parameters are natural values (not log space); gradients are
with respect to the model's free natural parameters.
"""
from __future__ import annotations

import hashlib
import logging
import time

import numpy as np
import pyopencl as cl

from brdfcl._words import count
from brdfcl.data.geometry import DEFAULT_CUTOFF_DEG, TABLE, table_geometry
from brdfcl.data.measurement import Layout
from brdfcl.device import buildlog, selftest, width
from brdfcl.device.cellsets import CellSet, Place, build_cellset, extract, read_stacked, read_values, select_cells
from brdfcl.device.platforms import has_fp64, is_cpu, pick_device, short_name
from brdfcl.device.program import (
    ProgramError,
    build,
    crash_guard,
    forget_binary,
    keep_attempt,
    keep_binary,
    load_binary,
    remember_pocl_cache,
    repair_pocl_cache,
)
from brdfcl.kernels.codegen import KernelOptions, jtj_pairs, kernel_names, n_outputs, render
from brdfcl.model.compose import Model
from brdfcl.model.metrics import METRICS

__all__ = ["CellSet", "Engine", "Place", "build_cellset", "context_for", "default_options", "extract",
           "read_stacked", "read_values", "select_cells"]

_log = logging.getLogger("brdfcl")
_CONTEXTS: dict = {}
_PROGRAMS: dict = {}


def context_for(selector=None):
    """(context, queue, device, platform) for a device selector, one per device per process."""
    platform, device = pick_device(selector)
    key = (platform.name, device.name, device.int_ptr)
    if key not in _CONTEXTS:
        ctx = cl.Context([device])
        _CONTEXTS[key] = (ctx, cl.CommandQueue(ctx), device, platform)
    return _CONTEXTS[key]


def default_options(device, real="float", **kw) -> KernelOptions:
    """Work layout for a device: vectors of ``vw`` cells per work-item on CPUs (the width comes
    from brdfcl.device.width, never from the device's own report), one cell per work-item on GPUs."""
    if is_cpu(device):
        local, chunk = 1, 256
    else:
        kw["vw"], local, chunk = 1, min(128, device.max_work_group_size), 4096
    kw.setdefault("local", local)
    kw.setdefault("chunk", chunk)
    return KernelOptions(real=real, **kw)


class Engine:
    """A model compiled for one device and metric; evaluates batches over a CellSet."""

    def __init__(self, model: Model | str, device=None, real="float", metric="log", cosw=True,
                 vector_width=None, verify=True, **options):
        """``vector_width``: cells per work-item on a CPU (default: brdfcl.device.width's tested choice);
        ``verify``: self-test the program against the float64 reference before it is used."""
        self.model = Model(model) if isinstance(model, str) else model
        self.ctx, self.queue, self.device, self.platform = context_for(device)
        if real == "double" and not has_fp64(self.device):
            raise ValueError(f"device {self.device.name} has no float64 support")
        self.width = None
        if "vw" not in options and is_cpu(self.device):
            self.width = width.choose(self.platform, self.device, real, vector_width, log=_log.info)
            options["vw"] = self.width.width
        self.opt = default_options(self.device, real, metric=metric, cosw=cosw, **options)
        self.dtype = np.float32 if real == "float" else np.float64
        self.source = render(self.model, self.opt)
        self.reported = tuple(METRICS)      # the errors kernel's sums, in order (brdfcl.model.metrics)
        self.pairs = jtj_pairs(self.model)
        self.n_out = n_outputs(self.model, len(self.pairs))
        self.kernel_names = kernel_names(self.model)
        self.program, self.self_test = self._compile(verify)
        self._kernels = {k: cl.Kernel(self.program, k) for k in self.kernel_names}

    def _compile(self, verify):
        """The program for this source, built once per process and device; a build whose kernels
        are missing or that fails the self-test is built again under a fresh cache key."""
        key = (hashlib.sha1(self.source.encode()).hexdigest(), self.device.int_ptr)
        if key in _PROGRAMS and (_PROGRAMS[key][1] is not None or not verify):
            return _PROGRAMS[key]
        repair_pocl_cache(self.platform, log=_log.warning)
        started = time.time_ns() - 2_000_000_000     # file times may lag the clock
        failures: list[ProgramError] = []
        with crash_guard(self.source, self.device, log=_log.warning) as first:
            kept = load_binary(self.ctx, self.device, self.source, first, self.kernel_names)
            if kept is not None:
                program, self._kernels = kept
                result = selftest.check(self) if verify else None
                if result is None or result.ok:
                    _PROGRAMS[key] = (program, result)
                    return _PROGRAMS[key]
                forget_binary(self.device, self.source, first)
            for attempt in (first, first + 1):
                try:
                    program, self._kernels = build(self.ctx, self.device, self.source, attempt, self.kernel_names)
                except ProgramError as e:
                    failures.append(e)
                    continue
                result = selftest.check(self) if verify else None
                if result is None or result.ok:
                    if result is not None:
                        remember_pocl_cache(self.platform, started)
                        keep_binary(program, self.device, self.source, attempt)
                    if failures:
                        keep_attempt(self.source, self.device, attempt)
                        _log.warning(f"brdfcl: rebuilt the {self.model.spec} program on {self.device.name}: "
                                     f"the cached build failed ({failures[0].cause})")
                    _PROGRAMS[key] = (program, result)
                    return _PROGRAMS[key]
                failures.append(ProgramError(f"self-test {result.detail}"))
        last = failures[-1]
        hint = f"; try a narrower --vector-width than {self.opt.vw}" if self.opt.vw > 1 and last.log is None else ""
        head = f"{self.model.spec} ({self.opt.real} x{self.opt.vw}) fails on {short_name(self.device)}: "
        raise ProgramError(buildlog.line(head, last.cause, last.log, hint), last.cause, last.log)

    # --- data ------------------------------------------------------------------------------------
    def cellset(self, tables, index=None, cutoff_deg=DEFAULT_CUTOFF_DEG, **kw) -> CellSet:
        """A cell set of measurements sharing the table layout (MerlTable objects) at the given cells."""
        index = select_cells(cutoff_deg) if index is None else np.asarray(index)
        names, (data,) = extract(tables, [index], self.dtype)
        return self.upload(names, index, data, **kw)

    def upload(self, names, index, data, weight_scale=None, layout: Layout = TABLE,
               cutoff_deg=DEFAULT_CUTOFF_DEG, max_alloc=None) -> CellSet:
        """A cell set of materials sharing one layout (by default the MERL table's), from their
        values (n_mat, C, n) already read at ``index``; ``weight_scale``: each cell's (a coarse
        subset's strides)."""
        place = Place(layout, np.asarray(index), 1.0 if weight_scale is None else weight_scale)
        return self.upload_places(names, [place], data, cutoff_deg, max_alloc)

    def upload_places(self, names, places, data, cutoff_deg=DEFAULT_CUTOFF_DEG, max_alloc=None,
                      own=False) -> CellSet:
        """A cell set of one shared Place ((n_mat, C, n) data) or one per material ([(C, n_i)]).
        ``own``: the data are the cell set's to keep (on a CPU device it reads them in place, and
        they become read-only)."""
        bad = [n for n, v in zip(names, data) if v.shape[0] != self.model.n_channels]
        if bad:
            raise ValueError(f"{bad[0]}: {count(data[list(names).index(bad[0])].shape[0], 'channel')}, but the "
                             f"model has {self.model.n_channels}")
        return build_cellset(self.ctx, names, places, data, self.dtype, pad_to=max(16, self.opt.vw),
                             cutoff_deg=cutoff_deg, max_alloc=max_alloc, own=own)

    def upload_cells(self, names, cells, weights, values) -> CellSet:
        """A cell set at arbitrary cells: per material its Cells, weights (n_i,) and values
        (C, n_i) (a quadrature's, a figure's)."""
        places = [Place(_GivenCells(c, w), np.arange(len(c))) for c, w in zip(cells, weights)]
        return self.upload_places(names, places, list(values), None)

    # --- launches --------------------------------------------------------------------------------
    def _params(self, values):
        values = np.atleast_2d(np.asarray(values, dtype=np.float64))
        return np.concatenate([values, self.model.consts(values)], axis=1).astype(self.dtype)

    def _targets(self, cs: CellSet) -> list:
        """Per data block, the buffer of the fit's targets g(m cw), made on the device once per
        cell set and metric (the target kernel): the loss, gradient and J^T J kernels read them
        instead of transforming the measured values at every evaluation."""
        key = (self.opt.metric, self.opt.cosw)
        if key not in cs.targets:
            bufs = []
            n_vec = cs.n_cells // self.opt.vw
            ng = max(1, -(-n_vec // self.opt.chunk))
            for first, n_block, dbuf in cs.blocks:
                tbuf = cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE, dbuf.size)
                mat = cl.Buffer(self.ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                                hostbuf=np.arange(n_block, dtype=np.int32))
                self._kernels["target"](self.queue, (n_block, ng * self.opt.local), (1, self.opt.local),
                                        cs.geom_buf, np.int32(cs.n_cells), np.int32(cs.geo_stride),
                                        np.int32(first), dbuf, dbuf, mat, tbuf)
                bufs.append(tbuf)
            cs.targets[key] = bufs
        return cs.targets[key]

    def _run(self, kname, cs: CellSet, values, mats):
        values = np.atleast_2d(values)
        mats = np.broadcast_to(np.asarray(mats, dtype=np.int32), (values.shape[0],))
        nout = self.n_out[kname]
        n_vec = cs.n_cells // self.opt.vw
        ng = max(1, -(-n_vec // self.opt.chunk))
        out = np.zeros((values.shape[0], nout))
        prm_all = self._params(values)
        kern = self._kernels[kname]
        mf = cl.mem_flags
        data = [b for _, _, b in cs.blocks] if kname == "errors" else self._targets(cs)
        for (first, n_block, _), dbuf in zip(cs.blocks, data):
            sel = np.flatnonzero((mats >= first) & (mats < first + n_block))
            if sel.size == 0:
                continue
            prm = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(prm_all[sel]))
            mat = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=(mats[sel] - first).astype(np.int32))
            part = np.empty((sel.size, ng, nout), dtype=self.dtype)
            obuf = cl.Buffer(self.ctx, mf.WRITE_ONLY, part.nbytes)
            kern(self.queue, (sel.size, ng * self.opt.local), (1, self.opt.local),
                 cs.geom_buf, np.int32(cs.n_cells), np.int32(cs.geo_stride), np.int32(first), dbuf, prm, mat, obuf)
            cl.enqueue_copy(self.queue, part, obuf)
            out[sel] = part.sum(axis=1, dtype=np.float64)
        return out

    def loss(self, cs, values, mats):
        """sum w r^2 per evaluation, shape (n,)."""
        return self._run("loss", cs, values, mats)[:, 0]

    def grad(self, cs, values, mats):
        """(loss (n,), gradient of the loss w.r.t. the free natural parameters (n, n_free))."""
        o = self._run("grad", cs, values, mats)
        return o[:, 0], 2.0 * o[:, 1:]

    def jtj(self, cs, values, mats):
        """(loss, J^T W r (n, k), J^T W J (n, k, k)) for Gauss-Newton steps."""
        o = self._run("jtj", cs, values, mats)
        k = self.model.n_free
        H = np.zeros((o.shape[0], k, k))
        for i, (a, b) in enumerate(self.pairs):
            H[:, a, b] = H[:, b, a] = o[:, 1 + k + i]
        return o[:, 0], o[:, 1:1 + k], H

    @property
    def has_meat(self) -> bool:
        """Whether this program sums the sandwich's middle term (`meat`; brdfcl.kernels.codegen)."""
        return "meat" in self.kernel_names

    def meat(self, cs, values, mats):
        """``M = sum_cells w^2 g g^T`` (n, k, k), ``g = sum_ch r dr/dtheta`` each cell's gradient
        (brdfcl.optim.uncertainty), over every cell of the set."""
        o = self._run("meat", cs, values, mats)
        k = self.model.n_free
        a, b = np.triu_indices(k)
        M = np.zeros((o.shape[0], k, k))
        M[:, a, b] = o
        M[:, b, a] = o
        return M

    def errors(self, cs, values, mats):
        """Reported errors (brdfcl.model.metrics) per evaluation: dict of arrays."""
        o = self._run("errors", cs, values, mats)
        n = len(self.reported)
        sw = np.maximum(o[:, n + 1], 1e-300)
        out = {f"rmse_{name}": np.sqrt(o[:, i] / sw) for i, name in enumerate(self.reported)}
        out["rel_rmse"] = np.sqrt(o[:, self.reported.index("l2")] / np.maximum(o[:, n], 1e-300))
        return out

    def tabulate(self, values):
        """Model values (C, N_CELLS) over the whole table for one parameter vector, NaN below the
        horizon (for exporting a fit as a MERL file); the table's geometry is uploaded once."""
        if getattr(self, "_table_cs", None) is None:
            idx = np.flatnonzero(table_geometry().above_horizon)
            self._table_cs = self.upload([], idx, np.zeros((0, self.model.n_channels, idx.size), self.dtype))
        out = np.full((self.model.n_channels, table_geometry().weight.size), np.nan)
        out[:, self._table_cs.index] = self.predict(self._table_cs, values)[0]
        return out

    def predict(self, cs, values, mats=0):
        """Model values (n, C, cells of the set) for each parameter vector (of material ``mats``:
        its geometry, for scattered samples)."""
        values = np.atleast_2d(values)
        prm = cl.Buffer(self.ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                        hostbuf=self._params(values))
        out = np.empty((values.shape[0], self.model.n_channels, cs.n_cells), dtype=self.dtype)
        mat = cl.Buffer(self.ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                        hostbuf=np.broadcast_to(np.asarray(mats, dtype=np.int32), (values.shape[0],)).copy())
        obuf = cl.Buffer(self.ctx, cl.mem_flags.WRITE_ONLY, out.nbytes)
        n_vec = cs.n_cells // self.opt.vw
        lw = 64 if self.opt.local > 1 else 1
        self._kernels["predict"](self.queue, (values.shape[0], -(-n_vec // lw) * lw), None,
                                 cs.geom_buf, np.int32(cs.n_cells), np.int32(cs.geo_stride), prm, mat, obuf)
        cl.enqueue_copy(self.queue, out, obuf)
        return out[:, :, :cs.index.size]


class _GivenCells(Layout):
    """Cells given as they are (brdfcl.model.lobes.cells.Cells with their weights)."""

    def __init__(self, cells, weights):
        self._cells, self._weights = cells, np.asarray(weights, dtype=np.float64)

    def select(self, cutoff_deg):
        return np.arange(len(self._cells))

    def weights(self, index, cutoff_deg):
        return self._weights[index]

    def rows(self, index):
        c = self._cells
        return c.sh[index], c.ch[index], c.cd[index], c.ci[index], c.co[index]
