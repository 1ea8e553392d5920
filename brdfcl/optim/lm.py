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

from brdfcl.optim.status import Status

JTJ = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
OnDone = Callable[[np.ndarray, np.ndarray, np.ndarray, list], None]
OnIter = Callable[[int, np.ndarray, np.ndarray, np.ndarray], None]


BEHIND_AFTER = 10
"""Iterations after which a row above its ``ceiling`` (`LMRun`) stops: a candidate whose loss is
still far above another's by then is not going to win."""


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
    """Every row's point, loss, iterations, evaluations (the start's included) and status
    (brdfcl.optim.status.Status)."""

    x: np.ndarray
    loss: np.ndarray
    iters: np.ndarray
    nfev: np.ndarray
    status: list = field(default_factory=list)


def _free(g, x, lo, hi):
    """Parameters (rows of x) not held at a bound by a gradient pointing outwards."""
    return ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))


def _on_free(H, g, free, pad):
    """Every row's system restricted to its free set, as one stack: H on the free block, ``pad``
    (per row) on the diagonal of the held parameters, g zero there, so that the held block is
    decoupled and solves to 0."""
    both = free[:, :, None] & free[:, None, :]
    eye = np.eye(H.shape[-1], dtype=bool)
    Hm = np.where(both, H, 0.0) + np.where(eye & ~free[:, :, None], pad[:, None, None], 0.0)
    return Hm, np.where(free, g, 0.0)


def newton_decrements(H, g, x, lo, hi):
    """g^T H^-1 g on each row's free set (m,): the loss decrease an undamped Gauss-Newton step
    predicts (inf where it overflows: such a row keeps running).  H may be singular: the
    pseudo-inverse, singular values below 1e-12 of the largest dropped (the held block is padded
    with the free block's largest diagonal, which the largest eigenvalue of a symmetric matrix is
    never below, so the padding does not move that cut)."""
    if H.shape[-1] == 0:
        return np.zeros(H.shape[0])
    free = _free(g, x, lo, hi)
    diag = np.diagonal(H, axis1=1, axis2=2)
    pad = np.maximum(np.max(np.where(free, np.abs(diag), 0.0), axis=1), 1e-300)
    Hm, gf = _on_free(H, g, free, pad)
    d = np.einsum("mij,mj->mi", np.linalg.pinv(Hm, rcond=1e-12, hermitian=True), gf)
    dec = np.maximum(np.einsum("mi,mi->m", gf, d), 0.0)
    return np.where(free.any(axis=1), np.where(np.isnan(dec), np.inf, dec), 0.0)


def lm_steps(H, g, x, lo, hi, lam):
    """Damped Gauss-Newton steps (m, k), one per row, with each row's active set removed:
    (H + lam diag(H)) d = -g on the free set, d = 0 on the held parameters."""
    if H.shape[-1] == 0:
        return np.zeros_like(g)
    free = _free(g, x, lo, hi)
    diag = np.where(free, np.diagonal(H, axis1=1, axis2=2), 0.0)
    dmax = np.max(diag, axis=1)
    diag = np.where(free, np.maximum(diag, 1e-12 * np.maximum(dmax, 1e-300)[:, None]), 0.0)
    pad = np.maximum(dmax, 1.0)
    Hm, gf = _on_free(H, g, free, pad)
    A = Hm + lam[:, None, None] * (diag[:, :, None] * np.eye(H.shape[-1]))
    try:
        d = np.linalg.solve(A, -gf[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:       # a singular row: each on its own, gradient steps where singular
        d = np.zeros_like(gf)
        for i in range(A.shape[0]):
            try:
                d[i] = np.linalg.solve(A[i], -gf[i])
            except np.linalg.LinAlgError:
                d[i] = np.where(free[i], -gf[i] / (np.where(free[i], diag[i], 1.0) * (1 + lam[i])), 0.0)
    d = np.where(free, d, 0.0)
    return np.where(np.isfinite(d).all(axis=1)[:, None], d, 0.0)


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
                 opts: LMOptions | None = None, floor: np.ndarray | None = None,
                 ceiling: np.ndarray | None = None):
        """``floor`` (n,): a loss at or below which a row has converged whatever its steps still
        change (the rounding noise of an exact fit: relative decreases there never settle);
        ``ceiling`` (n,): a loss above which a row stops after BEHIND_AFTER iterations
        (Status.BEHIND: a candidate another one beats)."""
        self.jtj_x, self.lo, self.hi = jtj_x, lo, hi
        self.floor = np.full(x0.shape[0], -np.inf) if floor is None else np.asarray(floor, dtype=np.float64)
        self.ceiling = None if ceiling is None else np.asarray(ceiling, dtype=np.float64)
        self.opts = opts or LMOptions()
        n = x0.shape[0]
        x = np.clip(x0, lo, hi).astype(np.float64)
        L, g, H = jtj_x(x, np.arange(n))
        L[~np.isfinite(L)] = np.inf
        self.g = np.where(np.isfinite(g), g, 0)
        self.H = np.where(np.isfinite(H), H, 0)
        self.state = LMState(x, L, np.zeros(n, dtype=int), np.ones(n, dtype=int), [Status.RUNNING] * n)
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
            trial = np.clip(x[rows] + lm_steps(H[rows], g[rows], x[rows], lo, hi, lam[rows]), lo, hi)
            # stop before launching at the floor, or where even an undamped Gauss-Newton step
            # would gain < ftol
            pred = newton_decrements(H[rows], g[rows], x[rows], lo, hi)
            floored = L[rows] <= self.floor[rows]
            behind = (np.zeros(rows.size, dtype=bool) if self.ceiling is None or it < BEHIND_AFTER
                      else L[rows] > self.ceiling[rows])
            flat = floored | behind | (pred <= opts.ftol * np.maximum(L[rows], 1e-300))
            for i, at_floor, left in zip(rows[flat], floored[flat], behind[flat]):
                status[i] = Status.NOISE_FLOOR if at_floor else Status.BEHIND if left else Status.PREDICTED_FTOL
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
                        status[i] = Status.FTOL
                else:
                    lam[i] *= 4
                    rejects[i] += 1
                    if lam[i] > opts.lam_max or rejects[i] >= opts.max_reject:
                        status[i] = Status.NO_DECREASE
                if status[i] != Status.RUNNING:
                    running[i] = False
                    done.append(i)
            yield LMStep(it, st, running, np.array(done, dtype=int), True)
        last = np.flatnonzero(running)
        for i in last:
            status[i] = Status.ITERATION_LIMIT
        running[last] = False
        if last.size:
            yield LMStep(opts.max_iter, st, running, last, False)


def levenberg_marquardt(jtj_x: JTJ, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                        opts: LMOptions | None = None, on_done: OnDone | None = None,
                        on_iter: OnIter | None = None, floor: np.ndarray | None = None,
                        ceiling: np.ndarray | None = None) -> LMState:
    """Minimise each row's loss from x0 (n, k).

    ``jtj_x(x (m, k), rows (m,)) -> (loss (m,), JTr (m, k), JTJ (m, k, k))`` in x space.
    ``on_done(rows, x, loss, status)`` is called with the rows that finish, as they do (before an
    iteration's launch, after it, at the iteration limit); ``on_iter(it, x, loss, running)`` after
    each launch; ``floor``, ``ceiling``: see `LMRun`.  `LMRun` gives the same moments as a loop
    instead of callbacks."""
    run = LMRun(jtj_x, x0, lo, hi, opts, floor, ceiling)
    st = run.state
    for step in run.steps():
        if step.evaluated and on_iter:
            on_iter(step.iteration, st.x, st.loss, step.running)
        if step.finished.size and on_done:
            on_done(step.finished, st.x, st.loss, st.status)
    return st
