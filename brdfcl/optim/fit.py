"""Fitting a model to a whole database at once: the pipeline of stages.

tables -> cell sets on the device (full table and a coarse subset) -> `global_search` on the
coarse set -> `pick_starts` on the preview cells (every n-th cell of the table; the full table
without a preview) -> Levenberg-Marquardt on the preview, then on the full table (`refine`)
-> `evaluate` and `assess` each material as it finishes -> `FitResult`.  Every stage batches all
materials into each launch and returns a `StageResult`.  The loss and its penalties are
brdfcl.optim.objective, the parameter spaces brdfcl.optim.spaces, the global search's methods
brdfcl.optim.search.

The names callers import from here (FitOptions, FitResult, GLOBAL_METHODS, coarse_cells,
select_cells, ...) stay importable from here.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from brdfcl.device.engine import Engine, extract, select_cells
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.optim.assessment import assess, bounds_hit, evaluate
from brdfcl.optim.lm import LMOptions
from brdfcl.optim.objective import Objective, Target, penalty_scale
from brdfcl.optim.options import GLOBAL_METHODS, FitOptions
from brdfcl.optim.refine import NOISE_FLOOR, refine
from brdfcl.optim.result import FitResult, StageResult
from brdfcl.optim.search import coarse_cells, global_search, material_seed, pick_starts

__all__ = ["GLOBAL_METHODS", "FitOptions", "FitResult", "Fitter", "LMOptions", "StageResult", "Targets",
           "bounds_hit", "coarse_cells", "extract", "fit_samples", "fit_tables", "load_batch", "material_seed",
           "select_cells"]


def _quiet(line: str) -> None:
    pass


@dataclass(frozen=True)
class Targets:
    """One batch on the device: the full table, the global search's coarse subset and, with
    ``FitOptions.preview_stride`` > 1, every n-th cell of the table for a first local pass."""

    full: Target
    coarse: Target
    preview: Target | None = None


class Fitter:
    """Compiled model + cell selection; `fit` runs the pipeline on one batch of materials."""

    assess_results = True   # attach standard errors, albedo and flags to each result (brdfcl.optim.assessment)

    def __init__(self, opts: FitOptions, engine: Engine | None = None, lambdas: Sequence[float] | None = None):
        """``lambdas``: the channels' wavelengths (um) when they are not the R, G, B of a MERL table
        (spectral samples: one per band)."""
        self.opts = opts
        self.lambdas = None if lambdas is None else tuple(float(x) for x in lambdas)
        channels = {} if self.lambdas is None else {"lambdas": self.lambdas}
        self.model = Model(opts.model, fixed=opts.fixed, **channels)
        self.engine = engine or Engine(self.model, device=opts.device, real=opts.real,
                                       metric=opts.metric, cosw=opts.cosw, vector_width=opts.vector_width)
        self.objective = Objective(self.engine, self.model, peak_order=opts.ct_peak)
        self.full_index = select_cells(opts.cutoff_deg)
        self.coarse_index, self.coarse_scale = coarse_cells(
            self.full_index, opts.coarse_stride, opts.coarse_peak_bins, opts.coarse_peak_stride)

    def targets(self, names: Sequence[str], full_data: np.ndarray, coarse_data: np.ndarray) -> Targets:
        """Upload a batch (values at ``full_index`` and ``coarse_index``, see `load_batch`); both
        sets carry the full table's penalty scale."""
        scale = penalty_scale(self.full_index, full_data)
        full = self.engine.upload(names, self.full_index, full_data)
        coarse = self.engine.upload(names, self.coarse_index, coarse_data, weight_scale=self.coarse_scale)
        s = self.opts.preview_stride
        preview = None
        if s > 1:
            preview = Target(self.engine.upload(names, self.full_index[s // 2::s], full_data[:, :, s // 2::s],
                                                weight_scale=float(s)), scale)
        return Targets(Target(full, scale), Target(coarse, scale), preview)

    def fit(self, names: Sequence[str], full_data: np.ndarray, coarse_data: np.ndarray,
            on_result: Callable[[FitResult], None] | None = None,
            log: Callable[[str], None] = _quiet, start: np.ndarray | None = None) -> list[FitResult]:
        """Fit every material; ``on_result(FitResult)`` is called as each one finishes.  ``start``
        (n, model parameters), natural values: a warm start, the local stage from there, no global
        search (e.g. a richer form from a simpler form's fit)."""
        t0 = time.perf_counter()
        return self.run(list(names), self.targets(names, full_data, coarse_data), full_data, t0, on_result, log,
                        start)

    def sample_targets(self, samples: Sequence) -> tuple[list[str], Targets, np.ndarray]:
        """Upload scattered measurements (brdfcl.data.samples.Samples, the model's channels): each
        material's samples inside the cut-off with their weights (``Samples.weights_within``), its
        own geometry.  The set is small, so the global search runs on all of it too.  Returns
        (names, targets, data (n_mat, C, longest) padded with NaN)."""
        names, cells, weights, values = [], [], [], []
        for s in samples:
            ok = s.mask(self.opts.cutoff_deg)
            names.append(s.name)
            cells.append(Cells.from_directions(s.wi[ok], s.wo[ok]))
            weights.append(np.asarray(s.weights_within(self.opts.cutoff_deg)[ok], dtype=np.float64))
            values.append(np.asarray(s.values[ok], dtype=np.float64).T)
        cs = self.engine.upload_samples(names, cells, weights, values)
        data = np.full((len(names), self.model.n_channels, cs.index.size), np.nan)
        for i, v in enumerate(values):
            data[i, :, :v.shape[1]] = v
        scale = np.array([np.sum(np.isfinite(v) * w) for v, w in zip(values, weights)])
        target = Target(cs, scale)
        return names, Targets(target, target), data

    def fit_samples(self, samples: Sequence, on_result: Callable[[FitResult], None] | None = None,
                    log: Callable[[str], None] = _quiet, start: np.ndarray | None = None) -> list[FitResult]:
        """Fit scattered measurements (Samples with the model's channels), all in one batch;
        ``start`` as in `fit`."""
        t0 = time.perf_counter()
        names, targets, data = self.sample_targets(samples)
        return self.run(names, targets, data, t0, on_result, log, start)

    def run(self, names: list[str], t: Targets, full_data: np.ndarray, t0: float,
            on_result: Callable[[FitResult], None] | None = None,
            log: Callable[[str], None] = _quiet, start_values: np.ndarray | None = None) -> list[FitResult]:
        """The pipeline on targets already on the device (``full_data``: their values, for the
        uncertainty); ``start_values``: see `fit`."""
        o, objective = self.opts, self.objective
        batch = _Batch(self, names, full_data, t.full, on_result, t0)
        ranking = t.full if t.preview is None else t.preview    # a few starts need no full table
        if start_values is None:
            found = global_search(objective, t.coarse, names=names, options=o, penalty=o.ct_peak_global, log=log)
            start = pick_starts(objective, ranking, found, n_materials=len(names))
        else:
            found = start = _warm_start(objective, np.asarray(start_values, dtype=np.float64), len(names))
        loss0 = start.fun
        if not np.isfinite(loss0).all():          # defaults taken: their loss was not evaluated
            loss0 = objective.loss(ranking, start.x, np.arange(len(names)))
        batch.started(found, loss0)
        x0, local, previewed = start.x, o, None
        if t.preview is not None:       # multi-resolution: converge on every n-th cell first
            previewed = _converged(refine(objective, t.preview, x0, options=o, log=log), len(names))
            batch.previewed(previewed)
            x0 = previewed.x
            local = replace(o, probe_dead_lobes=False, lm=replace(o.lm, max_iter=o.preview_final_iter))
        for step in refine(objective, t.full, x0, options=local, log=log):
            batch.progress(step.running, step.loss)
            if step.finished.mat.size:
                batch.finish(_finished_status(evaluate(objective, t.full, step.finished), previewed, step.start, o))
        return batch.results()


def _warm_start(objective: Objective, values: np.ndarray, n: int) -> StageResult:
    """Given start values as the global stage's result: one row per material, no evaluations
    (a value that is not finite takes the default, one beyond a bound the bound)."""
    if values.shape != (n, objective.model.n_params):
        raise ValueError(f"start values of shape {values.shape}: expected ({n}, {objective.model.n_params}), "
                         f"one row of every parameter of {objective.model.spec} per material")
    model = objective.model
    values = np.clip(np.where(np.isfinite(values), values, model.defaults()[None, :]), model.lo, model.hi)
    x = np.clip(objective.spaces.to_x(values), *objective.spaces.x_bounds)
    return StageResult(x, np.full(n, np.inf), np.arange(n), np.zeros(n, dtype=int), ["warm start"] * n,
                       np.ones(n, dtype=bool), "warm start")


SETTLED = 1e-3           # the full-table iterations lowered the loss by less than this, relative


def _finished_status(done: StageResult, previewed: StageResult | None, before: np.ndarray,
                     o: FitOptions) -> StageResult:
    """A row that converged on the preview cells and whose capped full-table iterations changed
    its loss by less than SETTLED (or that sits at the float32 floor) has converged: its status
    says so instead of "iteration limit"; one still improving keeps "iteration limit".  ``before``:
    each material's loss where the full-table iterations started."""
    if previewed is None:
        return done
    for j, i in enumerate(done.mat):
        if done.status[j] != "iteration limit" or not previewed.status[i].startswith("converged"):
            continue
        gain = (before[i] - done.fun[j]) / max(before[i], 1e-300)
        if gain < SETTLED or done.errors["rmse_log"][j] < NOISE_FLOOR:
            done.status[j] = (f"converged (on 1 in {o.preview_stride} cells; the {o.preview_final_iter} "
                              f"full-table iterations of the multi-resolution stage changed the loss by {gain:.1e})")
    return done


def _converged(steps, n: int) -> StageResult:
    """Every material's final row of a local stage run to its end (nothing handed out)."""
    rows: list = [None] * n
    for step in steps:
        for j, i in enumerate(step.finished.mat):
            rows[i] = step.finished.rows(np.array([j]))
    x = np.concatenate([r.x for r in rows])
    return StageResult(x, np.concatenate([r.fun for r in rows]), np.arange(n),
                       np.array([int(r.nfev[r.mat[0]]) for r in rows]), [r.status[0] for r in rows],
                       np.concatenate([r.success for r in rows]), "Levenberg-Marquardt on the preview cells")


class _Batch:
    """The bookkeeping of one `Fitter.fit`: clock, each material's history and evaluations, and the
    results, handed to ``on_result`` as materials finish."""

    def __init__(self, fitter: Fitter, names: list[str], data: np.ndarray, target: Target,
                 on_result: Callable[[FitResult], None] | None, t0: float):
        self.fitter, self.names, self.data, self.target, self.on_result = fitter, names, data, target, on_result
        self.t0 = t0
        self.history: list[list] = [[] for _ in names]
        self.done: list[FitResult | None] = [None] * len(names)
        self.global_nfev = np.zeros(len(names), dtype=int)
        self.t_global = self.t_assess = 0.0

    def now(self) -> float:
        return time.perf_counter() - self.t0

    def started(self, found: StageResult, loss: np.ndarray) -> None:
        """The global stage is over: ``found`` its result, ``loss`` the starts' (on the preview cells:
        weighted to estimate the full table's)."""
        self.t_global = self.now()
        self.global_nfev = found.nfev
        for i, h in enumerate(self.history):
            h.append((self.t_global, "global", float(np.sqrt(loss[i] / self.target.scale[i]))))

    def previewed(self, done: StageResult) -> None:
        """The preview pass is over: its evaluations count with the global stage's."""
        self.global_nfev = self.global_nfev + done.nfev

    def progress(self, running: np.ndarray, loss: np.ndarray) -> None:
        t = self.now()
        for i in running:
            self.history[i].append((t, "local", float(np.sqrt(loss[i] / self.target.scale[i]))))

    def finish(self, done: StageResult) -> None:
        """Assess the evaluated rows ``done`` and hand out their results."""
        t = self.now()
        f = self.fitter
        v = f.objective.spaces.values(done.x)
        judged: list[dict] = [{}] * len(done.mat)
        if f.assess_results:
            ta = time.perf_counter()
            judged = assess(f.objective, self.target, data=self.data, values=v, rows=done.mat, at_bound=done.bounds_hit)
            self.t_assess += time.perf_counter() - ta
        for j, i in enumerate(done.mat):
            self.history[i].append((t, "local", float(np.sqrt(done.fun[j] / self.target.scale[i]))))
            res = FitResult(name=self.names[i], model=f.model.spec, metric=f.opts.metric,
                            params=f.model.as_dict(v[j]), success=bool(done.success[j]), status=done.status[j],
                            loss=float(done.fun[j]), errors={k: float(e[j]) for k, e in done.errors.items()},
                            seconds=t, nfev=int(self.global_nfev[i] + done.nfev[i]), history=self.history[i],
                            bounds_hit=done.bounds_hit[j], stages={"global": self.t_global},
                            lambdas=self.fitter.lambdas, **judged[j])
            self.done[i] = res
            if self.on_result:
                self.on_result(res)

    def results(self) -> list[FitResult]:
        """Every material's result in batch order, with the time of each stage."""
        t_total = self.now()
        out = [r for r in self.done if r is not None]
        assert len(out) == len(self.names), "a material did not finish"
        for r in out:
            r.stages["local"] = t_total - self.t_global - self.t_assess
            if self.fitter.assess_results:
                r.stages["uncertainty"] = self.t_assess   # issue 17: assess() of the whole batch
            r.stages["total"] = t_total
        return out


def load_batch(items: Sequence, fitter: Fitter,
               on_error: Callable | None = None) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(names, full data, coarse data) for items that are MerlTables or callables returning one."""
    names, (full, coarse) = extract(items, [fitter.full_index, fitter.coarse_index],
                                    fitter.engine.dtype, on_error=on_error)
    return names, full, coarse


def fit_samples(samples: Sequence, opts: FitOptions | None = None, **kw) -> list[FitResult]:
    """Fit scattered measurements (brdfcl.data.samples.Samples) that share one set of channels,
    in one batch; the model gets one channel per band, at its wavelength."""
    opts = opts or FitOptions(**kw)
    samples = list(samples)
    bands = {tuple(s.wavelengths) for s in samples}
    if len(bands) != 1:
        raise ValueError(f"samples with {len(bands)} different sets of wavelengths: fit each set on its own")
    return Fitter(opts, lambdas=bands.pop()).fit_samples(samples)


def fit_tables(tables: Sequence, opts: FitOptions | None = None, **kw) -> list[FitResult]:
    """Fit MerlTable objects in one batch; returns a list of FitResult."""
    opts = opts or FitOptions(**kw)
    f = Fitter(opts)
    names, full, coarse = load_batch(tables, f)
    return f.fit(names, full, coarse)
