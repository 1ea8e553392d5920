"""Fitting a model to a whole database at once: global search, then local refinement.

Data flow: tables -> cell sets (coarse and full, on the device) -> global search
on the coarse set -> Levenberg-Marquardt on the full table -> `FitResult` per
material.  Every stage batches all materials into each launch.

Global search (``global_method``):
* ``lds`` (default): Sobol candidates in the bounded box, evaluated for all
  materials in one launch, then nlopt local searches (LD_LBFGS) from the best
  few per material, in lockstep; a batched form of MLSL with low-discrepancy starts.
* ``mlsl``: nlopt G_MLSL_LDS with LD_LBFGS local searches, in lockstep.
* ``crs2``: nlopt GN_CRS2_LM, in lockstep.
* ``none``: start the local refinement from the default values.
"""
from __future__ import annotations

import time
import zlib
from dataclasses import asdict, dataclass, field

import nlopt
import numpy as np
from scipy.stats import qmc

from brdfcl.data.geometry import DEFAULT_CUTOFF_DEG, table_geometry
from brdfcl.data.merl import N_PD, N_TD
from brdfcl.device.engine import Engine, extract, select_cells
from brdfcl.model.compose import DEFAULT_MODEL, Model
from brdfcl.optim.lm import LMOptions, levenberg_marquardt
from brdfcl.optim.lockstep import Problem, run_lockstep
from brdfcl.optim.peak_order import PeakOrder
from brdfcl.optim.uncertainty import assess, bounds_hit

GLOBAL_METHODS = ("lds", "mlsl", "crs2", "none")


@dataclass
class FitOptions:
    model: str = DEFAULT_MODEL
    metric: str = "log"
    cosw: bool = True
    cutoff_deg: float | None = DEFAULT_CUTOFF_DEG
    real: str = "float"
    device: str | None = None
    vector_width: int | None = None     # CPU cells per work-item; None: brdfcl.device.width decides
    global_method: str = "lds"
    n_candidates: int = 256         # lds: Sobol candidates per material
    n_starts: int = 4               # lds: local searches per material
    local_maxeval: int = 200        # per local search (lds) / whole search (mlsl, crs2: x 10)
    coarse_stride: int = 97         # coarse set: every n-th cell outside the peak region,
    coarse_peak_bins: int = 8       # every peak_stride-th cell with theta_h index below peak_bins
    coarse_peak_stride: int = 5
    lm: LMOptions = field(default_factory=LMOptions)
    seed: int = 0
    fixed: dict = field(default_factory=dict)
    probe_dead_lobes: bool = True   # revive a lobe that ends at zero amplitude at `probes` shapes
    probes: int = 4
    ct_peak: bool = False           # Cook-Torrance carries the specular peak (brdfcl.optim.peak_order)
    ct_peak_global: bool = True     # ... in the global search too (else only in the local stage)

    def __post_init__(self):
        if self.global_method not in GLOBAL_METHODS:
            raise ValueError(f"global method '{self.global_method}'; valid: {', '.join(GLOBAL_METHODS)}")


@dataclass
class FitResult:
    """One material's fit, in the spirit of scipy.optimize.OptimizeResult."""

    name: str
    model: str
    metric: str
    params: dict                     # natural values by parameter name
    success: bool
    status: str
    loss: float                      # sum w r^2 in the fit metric, full table
    errors: dict                     # rmse_l2, rmse_log, rmse_cbrt, rel_rmse
    seconds: float                   # wall time until this material was finished (launches are shared)
    nfev: int                        # evaluations of this material (coarse and full)
    history: list                    # [(seconds, stage, rmse in the fit metric)]
    bounds_hit: list
    stages: dict                     # seconds per stage (shared by the batch)
    # issue 17 (brdfcl.optim.uncertainty), in NAME.json's form; None / empty when not assessed
    uncertainty: dict | None = None  # {"std_error": {name: float|None}, "correlation": {...}, "method"}
    albedo: dict | None = None       # {"theta_i_deg": [...], "channels": [[r, g, b] per angle]}
    flags: list = field(default_factory=list)   # one line per reason not to trust the fit

    def as_dict(self):
        return asdict(self)


def coarse_cells(full_index, stride, peak_bins, peak_stride):
    """A coarse subset for the global search: denser near the specular peak, where sharp lobes
    live in few theta_h bins.  Weights are scaled by the strides so its loss estimates the full one."""
    th_idx = full_index // (N_TD * N_PD)
    peak = th_idx < peak_bins
    near = np.flatnonzero(peak)[::peak_stride]
    rest = np.flatnonzero(~peak)[::stride]
    idx = np.concatenate([near, rest])
    scale = np.concatenate([np.full(near.size, float(peak_stride)), np.full(rest.size, float(stride))])
    order = np.argsort(idx)
    return full_index[idx[order]], scale[order]


def material_seed(seed, name):
    return (seed * 1000003 + zlib.crc32(name.encode())) % (2 ** 31)


class Fitter:
    """Compiled model + cell sets for one batch of materials."""

    assess_results = True   # attach standard errors, albedo and flags to each result (brdfcl.optim.uncertainty)

    def __init__(self, opts: FitOptions, engine: Engine | None = None):
        self.opts = opts
        self.model = Model(opts.model, fixed=opts.fixed)
        self.engine = engine or Engine(self.model, device=opts.device, real=opts.real,
                                       metric=opts.metric, cosw=opts.cosw, vector_width=opts.vector_width)
        self.full_index = select_cells(opts.cutoff_deg)
        self._lin = self.model.amplitude[self.model.free_index]
        self.order = PeakOrder.for_model(self.model) if opts.ct_peak else None
        self._sw = None                 # per material sum of cell weights, the penalty's scale
        self.coarse_index, self.coarse_scale = coarse_cells(
            self.full_index, opts.coarse_stride, opts.coarse_peak_bins, opts.coarse_peak_stride)

    # --- objective in x space -------------------------------------------------------------------
    def _values(self, x):
        return self.model.from_x(x)

    # The peak constraint (self.order) makes the search harder in two ways: with it, most Sobol
    # candidates are infeasible and the feasible ones favour needle-sharp CT lobes; without it
    # (``ct_peak_global=False``), the optima may have the lobes' roles swapped, and walking them to
    # the constraint can end in a poor local minimum.  brdfcl.analysis.analyze fits both ways.
    def _loss(self, cs, x, mats, order=True):
        v = self._values(x)
        L = self.engine.loss(cs, v, mats)
        if order and self.order is not None:
            L = L + self.order.loss(v, self._sw[mats])
        return L

    def _grad_x(self, cs, x, mats, order=True):
        v = self._values(x)
        L, g = self.engine.grad(cs, v, mats)
        dv = self.model.dvalue_dx(v)
        g = g * dv
        if order and self.order is not None:
            r, J = self.order.residual(v, self._sw[mats])
            L = L + np.sum(r * r, axis=1)
            g = g + 2 * np.einsum("nc,nck->nk", r, J) * dv
        return L, g

    # Levenberg-Marquardt space: the model is linear in its amplitudes, so LM steps them in
    # natural units (Gauss-Newton is exact in them, and an amplitude at its lower bound is not
    # stuck on the flat of a log scale); shapes (alpha, a, ...) stay in log space.
    def to_lm(self, x):
        y = np.array(x, dtype=np.float64)
        y[..., self._lin] = np.exp(y[..., self._lin])
        return y

    def from_lm(self, y):
        x = np.array(y, dtype=np.float64)
        x[..., self._lin] = np.log(np.maximum(x[..., self._lin], 1e-300))
        return x

    def _jtj_lm(self, cs, y, mats):
        x = self.from_lm(y)
        v = self._values(x)
        L, r, H = self.engine.jtj(cs, v, mats)
        s = np.where(self._lin, 1.0, self.model.dvalue_dx(v))
        L, r, H = np.array(L, dtype=np.float64), r * s, H * s[:, :, None] * s[:, None, :]
        if self.order is not None:
            rp, Jp = self.order.residual(v, self._sw[mats])
            Jp = Jp * s[:, None, :]
            L = L + np.sum(rp * rp, axis=1)
            r = r + np.einsum("nc,nck->nk", rp, Jp)
            H = H + np.einsum("nci,ncj->nij", Jp, Jp)
        return L, r, H

    # --- stages -----------------------------------------------------------------------------------
    def global_search(self, cs, names, log, order=True):
        """Local optima on the coarse set: ([(material, x, coarse loss)], evaluations per material)."""
        m, o = self.model, self.opts
        n = len(names)
        lo, hi = m.x_lo, m.x_hi
        x_def = np.tile(m.to_x(m.defaults()), (n, 1))
        nfev = np.zeros(n, dtype=int)
        if o.global_method == "none":
            return [(i, x_def[i], np.inf) for i in range(n)], nfev
        if o.global_method == "lds":
            sob = qmc.Sobol(m.n_free, scramble=True, seed=o.seed).random(o.n_candidates)
            slo, shi = m.search_x_lo, m.search_x_hi
            cand = np.vstack([m.to_x(m.defaults()), slo + sob * (shi - slo)])
            nc = cand.shape[0]
            L = self._loss(cs, np.tile(cand, (n, 1)), np.repeat(np.arange(n), nc), order=order)
            L = np.where(np.isfinite(L), L, np.inf).reshape(n, nc)
            nfev += nc
            best = np.argsort(L[:, 1:], axis=1)[:, :o.n_starts] + 1
            log(f"global: {nc} Sobol candidates per material on {cs.index.size} cells; "
                f"local searches from the defaults and the best {o.n_starts}")
            starts = [(i, cand[j]) for i in range(n) for j in [0] + list(best[i])]
            algo, budget = nlopt.LD_LBFGS, o.local_maxeval
        else:
            starts = [(i, x_def[i]) for i in range(n)]
            algo = nlopt.G_MLSL_LDS if o.global_method == "mlsl" else nlopt.GN_CRS2_LM
            budget = 10 * o.local_maxeval
        problems = []
        for i, x0 in starts:
            opt = nlopt.opt(algo, m.n_free)
            opt.set_lower_bounds(lo)
            opt.set_upper_bounds(hi)
            opt.set_maxeval(budget)
            opt.set_ftol_rel(1e-7)
            if algo == nlopt.G_MLSL_LDS:
                loc = nlopt.opt(nlopt.LD_LBFGS, m.n_free)
                loc.set_ftol_rel(1e-6)
                loc.set_maxeval(o.local_maxeval // 2)
                opt.set_local_optimizer(loc)
            problems.append(Problem(opt, x0, material_seed(o.seed, names[i])))
        mats_of = np.array([i for i, _ in starts])

        def evaluate(xs, need, ids):
            mats = mats_of[ids]
            if need.any():
                return self._grad_x(cs, xs, mats, order=order)
            return self._loss(cs, xs, mats, order=order), np.zeros_like(xs)
        out = run_lockstep(problems, evaluate)
        for (i, _), oc in zip(starts, out):
            nfev[i] += oc.nfev
        return [(i, oc.x, oc.f) for (i, _), oc in zip(starts, out)], nfev

    def pick_starts(self, cs_full, outcomes, n, keep=3):
        """The best local outcome per material judged on the full table (the coarse loss only ranks)."""
        m = self.model
        x = np.tile(m.to_x(m.defaults()), (n, 1))
        by_mat = {}
        for i, xi, f in outcomes:
            by_mat.setdefault(i, []).append((f, xi))
        rows, xs = [], []
        for i, lst in by_mat.items():
            lst.sort(key=lambda t: t[0])
            for _, xi in lst[:keep]:
                rows.append(i)
                xs.append(xi)
        L = self._loss(cs_full, np.array(xs), np.array(rows))
        best = np.full(n, np.inf)
        for i, xi, li in zip(rows, xs, L):
            if np.isfinite(li) and li < best[i]:
                best[i], x[i] = li, xi
        return x

    def dead_lobes(self, x):
        """Lobes whose amplitudes all ended at the lower bound while they have a free shape: with no
        amplitude their shape has no gradient, so a local search cannot bring them back."""
        m = self.model
        cols = {n: k for k, n in enumerate(m.names[i] for i in m.free_index)}
        dead = []
        for lb in m.lobes:
            amp = [cols[s.name] for s in lb.slots() if s.name in cols and s.amplitude]
            shape = [cols[s.name] for s in lb.slots() if s.name in cols and not s.amplitude and s.param.log]
            if amp and shape and all(x[k] <= m.x_lo[k] + 1e-6 for k in amp):
                dead.append((amp, shape))
        return dead

    def _probe(self, queued, cs_full, ylo, yhi, lm_nfev, finish, log):
        """Revive each dead lobe at PROBES shapes spread over its search range, refine, keep the best."""
        m, o = self.model, self.opts
        slo, shi = m.search_x_lo, m.search_x_hi
        starts, owner = [], []
        for q, (_, x, _, _) in enumerate(queued):
            for amp, shape in self.dead_lobes(x):
                for k in range(o.probes):
                    xs = x.copy()
                    xs[amp] = 0.5 * (slo[amp] + shi[amp])
                    xs[shape] = slo[shape] + (k + 0.5) / o.probes * (shi[shape] - slo[shape])
                    starts.append(xs)
                    owner.append(q)
        owner = np.array(owner)
        mats = np.array([queued[q][0] for q in owner])
        log(f"local: {len(queued)} materials with a lobe at zero amplitude, {len(starts)} probes")

        def jtj(ys, rows):
            lm_nfev[mats[rows]] += 1
            return self._jtj_lm(cs_full, ys, mats[rows])
        st = levenberg_marquardt(jtj, self.to_lm(np.array(starts)), ylo, yhi, o.lm)
        xs = self.from_lm(st.x)
        best = {q: (queued[q][2], queued[q][1], queued[q][3]) for q in range(len(queued))}
        for j, q in enumerate(owner):
            if np.isfinite(st.loss[j]) and st.loss[j] < best[q][0]:
                best[q] = (st.loss[j], xs[j], st.status[j] + ", after reviving a lobe")
        finish([queued[q][0] for q in best], np.array([b[1] for b in best.values()]),
               np.array([b[0] for b in best.values()]), [b[2] for b in best.values()])

    def fit(self, names, full_data, coarse_data, on_result=None, log=lambda s: None):
        """Fit every material; ``on_result(FitResult)`` is called as each one finishes."""
        m, o, eng = self.model, self.opts, self.engine
        t0 = time.perf_counter()
        n = len(names)
        w_full = table_geometry().weight[self.full_index]
        sw = np.array([np.sum(np.isfinite(d) * w_full) for d in full_data])   # sum of w over channels
        self._sw = sw
        cs_full = eng.upload(names, self.full_index, full_data)
        cs_coarse = eng.upload(names, self.coarse_index, coarse_data, weight_scale=self.coarse_scale)
        history = [[] for _ in range(n)]
        outcomes, nfev = self.global_search(cs_coarse, names, log, order=o.ct_peak_global)
        x0 = self.pick_starts(cs_full, outcomes, n)
        t_global = time.perf_counter() - t0
        L0 = self._loss(cs_full, x0, np.arange(n))
        for i in range(n):
            history[i].append((t_global, "global", float(np.sqrt(L0[i] / sw[i]))))
        results = [None] * n

        def on_iter(it, x, L, running):
            t = time.perf_counter() - t0
            for i in np.flatnonzero(running):
                history[i].append((t, "local", float(np.sqrt(L[i] / sw[i]))))

        lm_nfev = np.zeros(n, dtype=int)
        queued = []
        t_assess = [0.0]

        def finish(rows, x, L, status):
            t = time.perf_counter() - t0
            rows = np.asarray(rows)
            v = self._values(x)
            err = eng.errors(cs_full, v, rows)
            hits = [bounds_hit(m, xj) for xj in x]
            # --- issue 17: standard errors, albedo, flags of the rows finishing now (one jtj launch)
            judged = [{}] * len(rows)
            if self.assess_results:
                ta = time.perf_counter()
                judged = assess(self, cs_full, full_data, v, rows, hits)
                t_assess[0] += time.perf_counter() - ta
            # ---
            for j, i in enumerate(rows):
                history[i].append((t, "local", float(np.sqrt(L[j] / sw[i]))))
                ok = bool(np.isfinite(L[j]) and all(np.isfinite(e[j]) for e in err.values()))
                hit = hits[j]
                res = FitResult(names[i], m.spec, o.metric, m.as_dict(v[j]), ok,
                                status[j] if ok else f"failed: {status[j]}, non-finite error",
                                float(L[j]), {k: float(e[j]) for k, e in err.items()}, t,
                                int(nfev[i] + lm_nfev[i]), history[i], hit, {"global": t_global},
                                **judged[j])
                results[i] = res
                if on_result:
                    on_result(res)

        def on_done(rows, y, L, status):
            x = self.from_lm(y[rows])
            direct = [j for j, i in enumerate(rows) if not (o.probe_dead_lobes and self.dead_lobes(x[j]))]
            queued.extend((rows[j], x[j], L[rows[j]], status[rows[j]]) for j in range(len(rows))
                          if j not in direct)
            if direct:
                finish(rows[direct], x[direct], L[rows[direct]], [status[rows[j]] for j in direct])

        def jtj(ys, rows):
            lm_nfev[rows] += 1
            return self._jtj_lm(cs_full, ys, rows)
        log(f"local: Levenberg-Marquardt on {self.full_index.size} cells per material")
        ylo, yhi = self.to_lm(m.x_lo), self.to_lm(m.x_hi)
        levenberg_marquardt(jtj, self.to_lm(x0), ylo, yhi, o.lm, on_done=on_done, on_iter=on_iter)
        if queued:
            self._probe(queued, cs_full, ylo, yhi, lm_nfev, finish, log)
        t_total = time.perf_counter() - t0
        for r in results:
            r.stages["local"] = t_total - t_global - t_assess[0]
            if self.assess_results:
                r.stages["uncertainty"] = t_assess[0]   # issue 17: assess() of the whole batch
            r.stages["total"] = t_total
        return results


def load_batch(items, fitter: Fitter, on_error=None):
    """(names, full data, coarse data) for items that are MerlTables or callables returning one."""
    names, (full, coarse) = extract(items, [fitter.full_index, fitter.coarse_index],
                                    fitter.engine.dtype, on_error=on_error)
    return names, full, coarse


def fit_tables(tables, opts: FitOptions | None = None, **kw):
    """Fit MerlTable objects in one batch; returns a list of FitResult."""
    opts = opts or FitOptions(**kw)
    f = Fitter(opts)
    names, full, coarse = load_batch(tables, f)
    return f.fit(names, full, coarse)
