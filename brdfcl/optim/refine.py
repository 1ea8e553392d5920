"""The local stage: Levenberg-Marquardt on the full table from one start per material, reviving
lobes that end at zero amplitude.

It runs as a sequence of `RefineStep`s, one whenever materials finish, so that the caller can
write their results as they arrive (between launches, outside the solver).  A material that
finishes with a dead lobe (`dead_lobes`) is held back: after the batched run, the lobe is revived
at ``FitOptions.probes`` shapes spread over its search range, each refined, and the best of those
and the held result is the material's result.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from brdfcl._words import count
from brdfcl.model.compose import Model
from brdfcl.optim.lm import LMRun, LMState, levenberg_marquardt
from brdfcl.optim.objective import Objective, Target
from brdfcl.optim.options import FitOptions
from brdfcl.optim.result import StageResult
from brdfcl.optim.status import Status

NOISE_FLOOR = 1e-5       # rmse_log below which a float32 fit is exact (its changes are rounding)


def _quiet(line: str) -> None:
    pass


def noise_floor(objective: Objective, target: Target, mats: np.ndarray) -> np.ndarray | None:
    """Per row, the loss of an rmse_log of NOISE_FLOOR on ``target`` (float32 engines; None for
    float64): where Levenberg-Marquardt stops an exact fit instead of stepping on rounding noise."""
    if np.dtype(objective.engine.dtype) != np.float32:
        return None
    return NOISE_FLOOR ** 2 * np.asarray(target.scale, dtype=np.float64)[mats]


@dataclass
class RefineStep:
    """Materials that finished at one moment of the local stage, and the loss of those running."""

    finished: StageResult           # one row per material finished now, at its final point
    running: np.ndarray             # materials still running after a launch (empty: no launch)
    loss: np.ndarray                # (n,) every material's current loss
    start: np.ndarray               # (n,) every material's loss at its start point


@dataclass
class _JTJ:
    """Levenberg-Marquardt's callback: rows of the run evaluated for their materials."""

    objective: Objective
    target: Target
    mats: np.ndarray                # material of each row of the run

    def __call__(self, y: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.objective.jtj(self.target, y, self.mats[rows])


def dead_lobes(model: Model, x: np.ndarray) -> list[tuple[list[int], list[int]]]:
    """Lobes whose amplitudes all ended at the lower bound while they have a free shape, as
    (amplitude columns, shape columns) of x: with no amplitude their shape has no gradient, so a
    local search cannot bring them back."""
    cols = {n: k for k, n in enumerate(model.names[i] for i in model.free_index)}
    dead = []
    for lb in model.lobes:
        amp = [cols[s.name] for s in lb.slots() if s.name in cols and s.amplitude]
        shape = [cols[s.name] for s in lb.slots() if s.name in cols and not s.amplitude and s.param.log]
        if amp and shape and all(x[k] <= model.x_lo[k] + 1e-6 for k in amp):
            dead.append((amp, shape))
    return dead


def _finished(objective: Objective, st: LMState, rows: np.ndarray, mats: np.ndarray, n: int) -> StageResult:
    """The run's ``rows`` as a stage result of the batch's ``n`` materials (row i fits ``mats[i]``)."""
    return StageResult(objective.spaces.from_y(st.x[rows]), st.loss[rows].copy(), mats[rows],
                       _per_material(st.nfev, mats, n, 0), [st.status[i] for i in rows],
                       np.isfinite(st.loss[rows]), "Levenberg-Marquardt")


def _per_material(values: np.ndarray, mats: np.ndarray, n: int, fill) -> np.ndarray:
    out = np.full(n, fill, dtype=values.dtype)
    out[mats] = values
    return out


def refine(objective: Objective, target: Target, x0: np.ndarray, *, options: FitOptions,
           log: Callable[[str], None] = _quiet, mats: np.ndarray | None = None,
           ceiling: np.ndarray | None = None) -> Iterator[RefineStep]:
    """Levenberg-Marquardt from ``x0`` (m, k), row i for material ``mats[i]`` of ``target`` (default:
    material i, every one): yields the materials as they finish (``nfev``: this stage's evaluations
    per material, probes included; materials not in ``mats`` have none and no loss).  ``ceiling``
    (per row): see `LMRun`; a row stopped there is not revived."""
    sp = objective.spaces
    n = len(target.scale)
    mats = np.arange(x0.shape[0]) if mats is None else np.asarray(mats, dtype=int)
    log(f"local: Levenberg-Marquardt on {target.cells.index.size} cells per material")
    run = LMRun(_JTJ(objective, target, mats), sp.to_y(x0), *sp.y_bounds, options.lm,
                noise_floor(objective, target, mats), ceiling)
    st = run.state
    start = _per_material(st.loss, mats, n, np.nan)
    held: list[int] = []            # rows finished with a dead lobe, revived at the end
    for step in run.steps():
        done = _finished(objective, st, step.finished, mats, n)
        dead = np.array([bool(options.probe_dead_lobes and st.status[r] != Status.BEHIND
                              and dead_lobes(objective.model, x)) for r, x in zip(step.finished, done.x)],
                        dtype=bool)
        held.extend(step.finished[dead].tolist())
        running = mats[np.flatnonzero(step.running)] if step.evaluated else np.zeros(0, dtype=int)
        yield RefineStep(done.rows(np.flatnonzero(~dead)), running, _per_material(st.loss, mats, n, np.nan), start)
    if held:
        cap = None
        if ceiling is not None:
            cap = np.full(n, np.inf)
            cap[mats] = ceiling
        revived = revive(objective, target, _finished(objective, st, np.array(held), mats, n), options=options,
                         log=log, ceiling=cap)
        revived.nfev += _per_material(st.nfev, mats, n, 0)
        yield RefineStep(revived, np.zeros(0, dtype=int), _per_material(st.loss, mats, n, np.nan), start)


def revive(objective: Objective, target: Target, held: StageResult, *, options: FitOptions,
           log: Callable[[str], None] = _quiet, ceiling: np.ndarray | None = None) -> StageResult:
    """Revive each dead lobe of the rows ``held`` at ``options.probes`` shapes spread over its
    search range (amplitude mid-range), refine each, and keep the best per row (the held point if
    no probe beats it).  ``ceiling`` (per material of the batch): a probe above its material's
    stops as a row of `refine` does (`LMRun`).  ``nfev``: per material, the launches that
    evaluated its probes (as the fit has always counted them: one per launch, however many probes
    it held)."""
    sp, model = objective.spaces, objective.model
    slo, shi = sp.search_box
    starts, owner = [], []
    for q, x in enumerate(held.x):
        for amp, shape in dead_lobes(model, x):
            for k in range(options.probes):
                xs = x.copy()
                xs[amp] = 0.5 * (slo[amp] + shi[amp])
                xs[shape] = slo[shape] + (k + 0.5) / options.probes * (shi[shape] - slo[shape])
                starts.append(xs)
                owner.append(q)
    out = StageResult(held.x.copy(), held.fun.copy(), held.mat, np.zeros_like(held.nfev), list(held.status),
                      held.success.copy(), "Levenberg-Marquardt, dead lobes revived",
                      notes=[held.note(j) for j in range(held.mat.size)])
    if not starts:                  # probes=0
        return out
    mats = held.mat[np.array(owner, dtype=int)]
    log(f"local: {count(len(held.mat), 'material')} with a lobe at zero amplitude, {count(len(starts), 'probe')}")
    st = levenberg_marquardt(_JTJ(objective, target, mats), sp.to_y(np.array(starts)), *sp.y_bounds,
                             options.lm, floor=noise_floor(objective, target, mats),
                             ceiling=None if ceiling is None else ceiling[mats])
    xs = sp.from_y(st.x)
    for j, q in enumerate(owner):
        if np.isfinite(st.loss[j]) and st.loss[j] < out.fun[q]:
            out.x[q], out.fun[q] = xs[j], st.loss[j]
            out.status[q] = st.status[j]
            out.notes[q] = "after reviving a lobe"
            out.success[q] = True
    np.maximum.at(out.nfev, mats, st.nfev)      # a material's probes share each launch: count it once
    return out
