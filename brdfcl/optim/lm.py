"""Batched, bounded Levenberg-Marquardt on J^T J from the kernels: every material steps together.

Works in the space of its callback (the fit uses Levenberg-Marquardt's y, brdfcl.optim.spaces).
One launch per iteration evaluates loss, J^T W r and J^T W J at the trial points of all
materials still running; a material whose trial lowers its loss accepts it
(damping / 3), otherwise it keeps its point (damping x 4).  Parameters at a
bound whose gradient points outwards are held (active set), so bounds never
stall the step.  `LMRun.steps` yields whenever rows finish, so that the caller can act on
them between launches; `levenberg_marquardt` is the same run with callbacks.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

JTJ = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
OnDone = Callable[[np.ndarray, np.ndarray, np.ndarray, list], None]
OnIter = Callable[[int, np.ndarray, np.ndarray, np.ndarray], None]


@dataclass
class LMOptions:
    """Stopping rules and damping of `levenberg_marquardt`."""

    max_iter: int = 60
    ftol: float = 1e-7            # stop after 3 accepted steps each lowering the loss less than this
    lam0: float = 1e-3
    lam_max: float = 1e10
    max_reject: int = 16          # consecutive rejected steps before stopping (float32 noise floor)


@dataclass
class LMState:
    """Every row's point, loss, iterations, evaluations (the start's included) and status."""

    x: np.ndarray
    loss: np.ndarray
    iters: np.ndarray
    nfev: np.ndarray
    status: list = field(default_factory=list)


def _free(g, x, lo, hi):
    return ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))


def newton_decrement(H, g, x, lo, hi):
    """g^T H^-1 g on the free set: the loss decrease an undamped Gauss-Newton step predicts."""
    free = _free(g, x, lo, hi)
    if not free.any():
        return 0.0
    gf = g[free]
    d = np.linalg.lstsq(H[np.ix_(free, free)], gf, rcond=1e-12)[0]
    return float(max(gf @ d, 0.0))


def _step(H, g, x, lo, hi, lam):
    """Damped Gauss-Newton step for one material with the active set removed."""
    k = x.size
    free = _free(g, x, lo, hi)
    d = np.zeros(k)
    if not free.any():
        return d
    Hf = H[np.ix_(free, free)]
    diag = np.diag(Hf).copy()
    diag = np.maximum(diag, 1e-12 * max(diag.max(), 1e-300))
    A = Hf + lam * np.diag(diag)
    try:
        d[free] = np.linalg.solve(A, -g[free])
    except np.linalg.LinAlgError:
        d[free] = -g[free] / (diag * (1 + lam))
    if not np.isfinite(d).all():
        d[:] = 0
    return d


@dataclass
class LMStep:
    """A moment of a run where rows may finish: before an iteration's launch (rows whose predicted
    decrease is below ftol), after it (``evaluated``: the iteration ended), and at the iteration
    limit.  ``state`` is the run's live state of every row: copy what must outlive the step."""

    iteration: int
    state: LMState
    running: np.ndarray          # (n,) bool: rows still running after this step
    finished: np.ndarray         # rows that finished at this step (may be empty)
    evaluated: bool              # trial points were evaluated: an iteration ended


class LMRun:
    """One batched run, as a sequence of `LMStep`: the caller can act on rows as they finish
    (write their results) between launches, outside the solver."""

    def __init__(self, jtj_x: JTJ, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 opts: LMOptions | None = None):
        self.jtj_x, self.lo, self.hi = jtj_x, lo, hi
        self.opts = opts or LMOptions()
        n = x0.shape[0]
        x = np.clip(x0, lo, hi).astype(np.float64)
        L, g, H = jtj_x(x, np.arange(n))
        L[~np.isfinite(L)] = np.inf
        self.g = np.where(np.isfinite(g), g, 0)
        self.H = np.where(np.isfinite(H), H, 0)
        self.state = LMState(x, L, np.zeros(n, dtype=int), np.ones(n, dtype=int), ["running"] * n)
        self.running = np.ones(n, dtype=bool)

    def steps(self) -> Iterator[LMStep]:
        """Iterate to the end; yields whenever rows finish and after every launch."""
        opts, lo, hi, st = self.opts, self.lo, self.hi, self.state
        x, L, g, H, status, running = st.x, st.loss, self.g, self.H, st.status, self.running
        n = x.shape[0]
        lam = np.full(n, opts.lam0)
        small = np.zeros(n, dtype=int)
        rejects = np.zeros(n, dtype=int)
        for it in range(opts.max_iter):
            rows = np.flatnonzero(running)
            if rows.size == 0:
                break
            trial = np.array([np.clip(x[i] + _step(H[i], g[i], x[i], lo, hi, lam[i]), lo, hi) for i in rows])
            # stop before launching where even an undamped Gauss-Newton step would gain < ftol
            pred = np.array([newton_decrement(H[i], g[i], x[i], lo, hi) for i in rows])
            flat = pred <= opts.ftol * np.maximum(L[rows], 1e-300)
            for i in rows[flat]:
                status[i] = "converged (predicted decrease below ftol)"
                running[i] = False
            if flat.any():
                yield LMStep(it, st, running, rows[flat], False)
            rows, trial = rows[~flat], trial[~flat]
            if rows.size == 0:
                continue
            Lt, gt, Ht = self.jtj_x(trial, rows)
            st.nfev[rows] += 1
            st.iters[rows] += 1
            done = []
            for j, i in enumerate(rows):
                ok = np.isfinite(Lt[j]) and Lt[j] < L[i] and np.isfinite(gt[j]).all() and np.isfinite(Ht[j]).all()
                if ok:
                    rel = (L[i] - Lt[j]) / max(L[i], 1e-300)
                    small[i] = small[i] + 1 if rel < opts.ftol else 0
                    x[i], L[i], g[i], H[i] = trial[j], Lt[j], gt[j], Ht[j]
                    lam[i] = max(lam[i] / 3, 1e-12)
                    rejects[i] = 0
                    if small[i] >= 3:
                        status[i] = "converged (ftol)"
                else:
                    lam[i] *= 4
                    rejects[i] += 1
                    if lam[i] > opts.lam_max or rejects[i] >= opts.max_reject:
                        status[i] = "converged (no further decrease)"
                if status[i] != "running":
                    running[i] = False
                    done.append(i)
            yield LMStep(it, st, running, np.array(done, dtype=int), True)
        last = np.flatnonzero(running)
        for i in last:
            status[i] = "iteration limit"
        running[last] = False
        if last.size:
            yield LMStep(opts.max_iter, st, running, last, False)


def levenberg_marquardt(jtj_x: JTJ, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                        opts: LMOptions | None = None, on_done: OnDone | None = None,
                        on_iter: OnIter | None = None) -> LMState:
    """Minimise each row's loss from x0 (n, k).

    ``jtj_x(x (m, k), rows (m,)) -> (loss (m,), JTr (m, k), JTJ (m, k, k))`` in x space.
    ``on_done(rows, x, loss, status)`` is called with the rows that finish, as they do (before an
    iteration's launch, after it, at the iteration limit); ``on_iter(it, x, loss, running)`` after
    each launch.  `LMRun` gives the same moments as a loop instead of callbacks."""
    run = LMRun(jtj_x, x0, lo, hi, opts)
    st = run.state
    for step in run.steps():
        if step.evaluated and on_iter:
            on_iter(step.iteration, st.x, st.loss, step.running)
        if step.finished.size and on_done:
            on_done(step.finished, st.x, st.loss, st.status)
    return st
