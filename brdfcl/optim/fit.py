"""Fitting a model to a whole database at once: the pipeline of stages.

measurements (brdfcl.data.measurement) -> cell sets on the device (the fitted cells and, for a
dense layout such as a table's, a coarse subset and every n-th cell) -> `global_search` on the
coarse set -> `pick_starts` on the preview cells (the fitted cells without a preview) ->
Levenberg-Marquardt on the preview, then on every fitted cell (`refine`) -> `evaluate` and
`assess` each material as it finishes -> `FitResult`.  Every stage batches all materials into
each launch and returns a `StageResult`.  One path for every format: what differs between a
table and scattered samples is their layout's, not the fit's.  The loss and its penalties are
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

from brdfcl._words import count
from brdfcl.data.geometry import coarse_cells
from brdfcl.data.measurement import Measurement
from brdfcl.device.engine import Engine, Place, extract, read_stacked, read_values, select_cells
from brdfcl.model.compose import Model
from brdfcl.optim.assessment import assess, bounds_hit, evaluate
from brdfcl.optim.lm import LMOptions
from brdfcl.optim.objective import Objective, Target
from brdfcl.optim.options import GLOBAL_METHODS, FitOptions
from brdfcl.optim.refine import NOISE_FLOOR, refine
from brdfcl.optim.result import FitResult, StageResult
from brdfcl.optim.search import global_search, material_seed, pick_starts
from brdfcl.optim.status import Status

__all__ = ["GLOBAL_METHODS", "FitOptions", "FitResult", "Fitter", "LMOptions", "Loaded", "StageResult", "Targets",
           "bounds_hit", "coarse_cells", "extract", "fit", "fit_samples", "fit_tables", "material_seed",
           "select_cells"]


def _quiet(line: str) -> None:
    pass


@dataclass(frozen=True)
class Targets:
    """One batch on the device: the fitted cells, the global search's coarse subset and, with
    ``FitOptions.preview_stride`` > 1 on a dense layout, every n-th cell for a first local pass."""

    full: Target
    coarse: Target
    preview: Target | None = None


@dataclass(frozen=True)
class Loaded:
    """A batch read and on the device: the names of the measurements that could be read, their
    targets, and their values at the fitted cells ((n, C, cells), NaN-padded per material)."""

    names: list
    targets: Targets
    data: np.ndarray
    read: list               # positions in the given measurements of those read


class Fitter:
    """Compiled model + cell selection; `fit` runs the pipeline on one batch of measurements."""

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

    @property
    def full_index(self) -> np.ndarray:
        """The fitted cells of a MERL table."""
        return select_cells(self.opts.cutoff_deg)

    def places(self, m: Measurement, dense: bool) -> list[Place]:
        """A measurement's cells in each stage: fitted, coarse and (with a preview) every n-th."""
        o = self.opts
        full = m.layout.select(o.cutoff_deg)
        if not dense:
            return [Place(m.layout, full)]
        coarse, scale = m.layout.coarse(full, o.coarse_stride, o.coarse_peak_bins, o.coarse_peak_stride)
        out = [Place(m.layout, full), Place(m.layout, coarse, scale)]
        s = o.preview_stride
        if s > 1:
            out.append(Place(m.layout, full[s // 2::s], float(s)))
        return out

    def load(self, measurements: Sequence[Measurement], on_error: Callable | None = None) -> Loaded:
        """Read a batch and upload it: a batch whose measurements share one layout (tables) shares
        one geometry; on a dense layout (every one's) the global search gets a coarse subset and,
        with ``preview_stride`` > 1, the local search every n-th cell first.  A measurement that
        cannot be read goes to ``on_error(measurement, exc)`` (raised without one)."""
        ms = list(measurements)
        bad = [m for m in ms if m.n_channels != self.model.n_channels]
        if bad:
            raise ValueError(f"{bad[0].path or bad[0].name}: {count(bad[0].n_channels, 'channel')}, but the model has "
                             f"{self.model.n_channels}")
        dense = bool(ms) and all(m.layout.dense for m in ms)
        shared = bool(ms) and all(m.layout is ms[0].layout for m in ms)
        if shared:
            common = self.places(ms[0], dense)
            places = [common] * len(ms)
        else:
            places = [self.places(m, dense) for m in ms]
        if shared:
            read, stacked = read_stacked(ms, [p.index for p in common], self.engine.dtype, on_error)
            values = [[s[i] for s in stacked] for i in range(len(read))]
        else:
            read, values = read_values(ms, lambda k: [p.index for p in places[k]], self.engine.dtype, on_error)
        names = [ms[k].name for k in read]
        places = [places[k] for k in read]
        n_sets = len(places[0]) if places else 1

        def stage(j: int) -> tuple:
            if shared:
                return [common[j]], stacked[j]
            return [p[j] for p in places], [v[j] for v in values]

        cut = self.opts.cutoff_deg
        full_places, full_data = stage(0)
        scale = finite_weights([v[0] for v in values], [p[0] for p in places], cut)
        sets = []
        for j in range(n_sets):
            at, values_j = stage(j)
            sets.append(self.engine.upload_places(names, at, values_j, cutoff_deg=cut, own=True))
        full = Target(sets[0], scale)
        coarse = Target(sets[1], scale) if n_sets > 1 else full
        preview = Target(sets[2], scale) if n_sets > 2 else None
        if shared:
            data = full_data
        else:
            data = np.full((len(names), self.model.n_channels, sets[0].index.size), np.nan, self.engine.dtype)
            for i, v in enumerate(full_data):
                data[i, :, :v.shape[1]] = v
        return Loaded(names, Targets(full, coarse, preview), data, read)

    def fit(self, measurements: Sequence[Measurement], on_result: Callable[[FitResult], None] | None = None,
            log: Callable[[str], None] = _quiet, start: np.ndarray | None = None,
            on_error: Callable | None = None) -> list[FitResult]:
        """Fit every measurement of a batch (the model's channels; see `load`); ``on_result(FitResult)``
        is called as each one finishes.  ``start`` (n, model parameters), natural values: a warm
        start, the local stage from there, no global search (e.g. a richer form from a simpler
        form's fit).  A measurement that cannot be read goes to ``on_error`` and has no result."""
        t0 = time.perf_counter()
        b = self.load(measurements, on_error)
        if start is not None:
            start = np.asarray(start)[b.read]
        return self.fit_loaded(b, on_result, log, start, t0)

    def fit_loaded(self, b: Loaded, on_result: Callable[[FitResult], None] | None = None,
                   log: Callable[[str], None] = _quiet, start: np.ndarray | None = None,
                   t0: float | None = None) -> list[FitResult]:
        """`fit` on a batch already read and uploaded (by a fitter whose cells this one can read,
        `same_cells`)."""
        if not b.names:
            return []
        return self.run(b.names, b.targets, b.data, time.perf_counter() if t0 is None else t0, on_result, log,
                        start)

    def run(self, names: list[str], t: Targets, full_data: np.ndarray, t0: float,
            on_result: Callable[[FitResult], None] | None = None,
            log: Callable[[str], None] = _quiet, start_values: np.ndarray | None = None) -> list[FitResult]:
        """The pipeline on targets already on the device (``full_data``: their values, for the
        uncertainty); ``start_values``: see `fit`."""
        return self.complete(self.begin(names, t, full_data, t0, on_result, log, start_values), log)

    def begin(self, names: list[str], t: Targets, full_data: np.ndarray, t0: float,
              on_result: Callable[[FitResult], None] | None = None,
              log: Callable[[str], None] = _quiet, start_values: np.ndarray | None = None,
              ceiling: np.ndarray | None = None, mats: np.ndarray | None = None) -> Begun:
        """`run` up to the full-table stage: the global search (or the warm start) and, with a
        preview set, Levenberg-Marquardt on it to convergence; `complete` finishes it.
        ``ceiling`` (n,): each material's rmse in the fit metric (penalties included) above which
        its preview run stops early (brdfcl.optim.lm.BEHIND_AFTER; Status.BEHIND).  ``mats``: with
        a preview set and start values, the materials fitted on it (default: every one); the others
        keep their start, with no loss (no estimate) and no success, and are not to be completed."""
        o, objective = self.opts, self.objective
        n = len(names)
        batch = _Batch(self, names, full_data, t.full, on_result, t0)
        ranking = t.full if t.preview is None else t.preview    # a few starts need no full table
        rows = np.arange(n) if mats is None else np.asarray(mats, dtype=int)
        if mats is not None and (start_values is None or t.preview is None):
            raise ValueError("a subset of materials is fitted on the preview cells from start values only")
        if start_values is None:
            found = global_search(objective, t.coarse, names=names, options=o, penalty=o.ct_peak_global, log=log)
            start = pick_starts(objective, ranking, found, n_materials=n)
        else:
            found = start = _warm_start(objective, np.asarray(start_values, dtype=np.float64), n)
        loss0 = start.fun
        if not np.isfinite(loss0).all():          # defaults taken: their loss was not evaluated
            loss0 = np.full(n, np.nan)
            if rows.size:
                loss0[rows] = objective.loss(ranking, start.x[rows], rows)
        batch.started(found, loss0)
        x0, local, previewed = start.x, o, None
        if t.preview is not None:       # multi-resolution: converge on every n-th cell first
            cap = None if ceiling is None else (np.asarray(ceiling, dtype=np.float64) ** 2 * t.full.scale)[rows]
            steps = refine(objective, t.preview, x0[rows], options=o, log=log, ceiling=cap, mats=rows)
            previewed = _converged(steps if rows.size else (), x0)
            batch.previewed(previewed)
            x0 = previewed.x
            local = replace(o, probe_dead_lobes=False, lm=replace(o.lm, max_iter=o.preview_final_iter))
        batch.suspend()
        return Begun(self, t, batch, x0, local, previewed)

    def complete(self, b: Begun, log: Callable[[str], None] = _quiet,
                 mats: np.ndarray | None = None) -> list[FitResult]:
        """The full-table stage of a `begin`, for the materials ``mats`` (default: all), their
        results in that order; each material is completed once."""
        objective, t = self.objective, b.targets
        rows = np.arange(len(b.batch.names)) if mats is None else np.asarray(mats, dtype=int)
        b.batch.resume()
        if rows.size:
            for step in refine(objective, t.full, b.x0[rows], options=b.local, log=log, mats=rows):
                b.batch.progress(step.running, step.loss, step.finished.mat)
                if step.finished.mat.size:
                    b.batch.finish(_finished_status(evaluate(objective, t.full, step.finished), b.previewed,
                                                    step.start, self.opts))
        out = b.batch.results(rows)
        b.batch.suspend()
        return out


@dataclass
class Begun:
    """A batch's fit up to its full-table stage (`Fitter.begin`): the start of that stage per
    material, and, with a preview set, where Levenberg-Marquardt converged on it."""

    fitter: Fitter
    targets: Targets
    batch: _Batch
    x0: np.ndarray                   # (n, k) optimiser space: each material's start on the full table
    local: FitOptions                # the full-table stage's options
    previewed: StageResult | None    # the preview pass (None: no preview set)

    def values(self) -> np.ndarray:
        """(n, parameters) natural values at the full-table stage's start."""
        return self.fitter.objective.spaces.values(self.x0)

    def estimate(self) -> np.ndarray | None:
        """(n,) each material's rmse in the fit metric on the preview cells (weighted to stand for
        the full table), penalties included; None without a preview."""
        if self.previewed is None:
            return None
        return np.sqrt(np.maximum(self.previewed.fun, 0) / self.targets.full.scale)

    def starts(self) -> list[StartPoint]:
        """Each material's full-table start as a source for another form's warm start."""
        model = self.fitter.model
        ok = np.ones(len(self.x0), dtype=bool) if self.previewed is None else self.previewed.success
        return [StartPoint(model.as_dict(v), bool(s)) for v, s in zip(self.values(), ok)]


@dataclass(frozen=True)
class StartPoint:
    """A fit's parameters where a warm start can read them (as a FitResult's)."""

    params: dict
    success: bool


def finite_weights(values: Sequence[np.ndarray], places: Sequence[Place], cutoff_deg: float | None) -> np.ndarray:
    """Each material's sum of its cells' weights over the channels where its value is finite (the
    loss's normalisation: a fit's rmse is sqrt(loss / this)); ``values[k]`` (C, n) at the cells of
    ``places[k]``.  A place that several materials share has its weights made once, and a
    material without a missing value (one sum finds it: NaN and inf carry through) costs that sum."""
    made: dict[int, tuple[np.ndarray, float]] = {}
    out = np.empty(len(values))
    for k, (v, p) in enumerate(zip(values, places)):
        if id(p) not in made:
            w = p.weights(cutoff_deg)
            made[id(p)] = (w, float(w.sum()))
        w, total = made[id(p)]
        if np.isfinite(np.sum(v)):
            out[k] = v.shape[0] * total
        else:
            out[k] = float(np.isfinite(v).sum(axis=0, dtype=np.uint16) @ w)
    return out


def same_cells(a: Fitter, b: Fitter) -> bool:
    """Whether two fitters' engines can read one upload: the same OpenCL context (one per device
    in a process), precision, padding, target transform and cells."""
    ea, eb = a.engine, b.engine
    cells = ("cutoff_deg", "coarse_stride", "coarse_peak_bins", "coarse_peak_stride", "preview_stride")
    return (ea.ctx is eb.ctx and ea.dtype == eb.dtype and max(16, ea.opt.vw) == max(16, eb.opt.vw)
            and (ea.opt.metric, ea.opt.cosw) == (eb.opt.metric, eb.opt.cosw)
            and all(getattr(a.opts, k) == getattr(b.opts, k) for k in cells))


def _warm_start(objective: Objective, values: np.ndarray, n: int) -> StageResult:
    """Given start values as the global stage's result: one row per material, no evaluations
    (a value that is not finite takes the default, one beyond a bound the bound)."""
    if values.shape != (n, objective.model.n_params):
        raise ValueError(f"start values of shape {values.shape}: expected ({n}, {objective.model.n_params}), "
                         f"one row of every parameter of {objective.model.spec} per material")
    model = objective.model
    values = np.clip(np.where(np.isfinite(values), values, model.defaults()[None, :]), model.lo, model.hi)
    x = np.clip(objective.spaces.to_x(values), *objective.spaces.x_bounds)
    return StageResult(x, np.full(n, np.inf), np.arange(n), np.zeros(n, dtype=int), [Status.START] * n,
                       np.ones(n, dtype=bool), "warm start", notes=["warm start"] * n)


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
        if done.status[j] != Status.ITERATION_LIMIT or not Status(previewed.status[i]).converged:
            continue
        gain = (before[i] - done.fun[j]) / max(before[i], 1e-300)
        if gain < SETTLED or done.errors["rmse_log"][j] < NOISE_FLOOR:
            done.status[j] = Status.SETTLED
            if not done.notes:
                done.notes = [""] * done.mat.size
            done.notes[j] = (f"1 cell in {o.preview_stride}; the {o.preview_final_iter} full-table iterations "
                             f"changed the loss by {gain:.1e}")
    return done


def _converged(steps, x0: np.ndarray) -> StageResult:
    """Every material's final row of a local stage run to its end (nothing handed out); a material
    the run did not hold keeps its start ``x0`` (n, k), with no loss, no evaluation and no success."""
    n = len(x0)
    x, fun, nfev = np.array(x0, dtype=np.float64), np.full(n, np.nan), np.zeros(n, dtype=int)
    status, success, notes = [Status.START] * n, np.zeros(n, dtype=bool), ["not fitted in this form"] * n
    for step in steps:
        for j, i in enumerate(step.finished.mat):
            r = step.finished.rows(np.array([j]))
            x[i], fun[i], nfev[i], status[i], success[i], notes[i] = (r.x[0], r.fun[0], int(r.nfev[i]), r.status[0],
                                                                      r.success[0], r.note(0))
    return StageResult(x, fun, np.arange(n), nfev, status, success, "Levenberg-Marquardt on the preview cells",
                       notes=notes)


class _Batch:
    """The bookkeeping of one `Fitter.fit`: clock, each material's history, evaluations and share of
    the wall time, and the results, handed to ``on_result`` as materials finish.

    A launch serves every material in it, so a material's time is its share: each interval split
    evenly among the materials being fitted then (all of them until the local stage, the running
    ones during it, the assessed ones for their assessment); the shares of a batch sum to its wall
    time."""

    def __init__(self, fitter: Fitter, names: list[str], data: np.ndarray, target: Target,
                 on_result: Callable[[FitResult], None] | None, t0: float):
        self.fitter, self.names, self.data, self.target, self.on_result = fitter, names, data, target, on_result
        self.t0 = t0
        self.history: list[list] = [[] for _ in names]
        self.done: list[FitResult | None] = [None] * len(names)
        self.global_nfev = np.zeros(len(names), dtype=int)
        self.t_global = self.t_assess = 0.0
        self.share = np.zeros(len(names))
        self.mark = 0.0
        self.idle = 0.0                 # time suspended (other forms' stages run meanwhile)
        self.suspended: float | None = None

    def spend(self, mats) -> float:
        """Split the time since the last mark among ``mats``; the time now."""
        t = self.now()
        mats = np.asarray(mats, dtype=int)
        if mats.size:
            self.share[mats] += (t - self.mark) / mats.size
        self.mark = t
        return t

    def now(self) -> float:
        return time.perf_counter() - self.t0 - self.idle

    def suspend(self) -> None:
        """Stop the clock: what runs until `resume` is not this batch's."""
        self.spend([])
        self.suspended = time.perf_counter()

    def resume(self) -> None:
        if self.suspended is not None:
            self.idle += time.perf_counter() - self.suspended
            self.mark = self.now()
            self.suspended = None

    def started(self, found: StageResult, loss: np.ndarray) -> None:
        """The global stage is over: ``found`` its result, ``loss`` the starts' (on the preview cells:
        weighted to estimate the full table's)."""
        self.t_global = self.spend(np.arange(len(self.names)))
        self.global_nfev = found.nfev
        for i, h in enumerate(self.history):
            h.append((self.t_global, "global", float(np.sqrt(loss[i] / self.target.scale[i]))))

    def previewed(self, done: StageResult) -> None:
        """The preview pass is over: its evaluations count with the global stage's."""
        self.spend(np.arange(len(self.names)))
        self.global_nfev = self.global_nfev + done.nfev

    def progress(self, running: np.ndarray, loss: np.ndarray, finished: np.ndarray) -> None:
        """A step of the local stage: ``running`` still, ``finished`` now."""
        t = self.spend(np.union1d(running, finished))
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
            self.spend(done.mat)
        for j, i in enumerate(done.mat):
            self.history[i].append((t, "local", float(np.sqrt(done.fun[j] / self.target.scale[i]))))
            res = FitResult(name=self.names[i], model=f.model.spec, metric=f.opts.metric,
                            params=f.model.as_dict(v[j]), success=bool(done.success[j]),
                            status=int(done.status[j]), message=done.row_message(j),
                            loss=float(done.fun[j]), errors={k: float(e[j]) for k, e in done.errors.items()},
                            seconds=float(self.share[i]), nfev=int(self.global_nfev[i] + done.nfev[i]),
                            history=self.history[i],
                            bounds_hit=done.bounds_hit[j], stages={"global": self.t_global},
                            lambdas=self.fitter.lambdas, **judged[j])
            self.done[i] = res
            if self.on_result:
                self.on_result(res)

    def results(self, rows: np.ndarray) -> list[FitResult]:
        """The results of the materials ``rows``, in that order, with the time of each stage."""
        t_total = self.now()
        out = [r for r in (self.done[i] for i in rows) if r is not None]
        assert len(out) == len(rows), "a material did not finish"
        for r in out:
            r.stages["local"] = t_total - self.t_global - self.t_assess
            if self.fitter.assess_results:
                r.stages["uncertainty"] = self.t_assess   # assess() of the whole batch
            r.stages["total"] = t_total
        return out


def fit(measurements: Sequence[Measurement], opts: FitOptions | None = None, **kw) -> list[FitResult]:
    """Fit measurements (any format, brdfcl.data.readers.read_measurement) that share one set of
    channels, in one batch; the model gets one channel per band, at its wavelength."""
    opts = opts or FitOptions(**kw)
    measurements = list(measurements)
    bands = {tuple(float(x) for x in m.wavelengths) for m in measurements}
    if len(bands) != 1:
        raise ValueError(f"measurements with {len(bands)} different sets of wavelengths: fit each set on its own")
    lambdas = bands.pop()
    rgb = lambdas == tuple(Model(opts.model).lambdas)
    return Fitter(opts, lambdas=None if rgb else lambdas).fit(measurements)


fit_samples = fit
fit_tables = fit
"""``fit`` under the names of its inputs (scattered samples, MERL tables)."""
