"""Batched, bounded Levenberg-Marquardt on J^T J from the kernels: every material steps together.

Works in the optimiser's space x (log space where flagged).  One launch per
iteration evaluates loss, J^T W r and J^T W J at the trial points of all
materials still running; a material whose trial lowers its loss accepts it
(damping / 3), otherwise it keeps its point (damping x 4).  Parameters at a
bound whose gradient points outwards are held (active set), so bounds never
stall the step.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class LMOptions:
    max_iter: int = 60
    ftol: float = 1e-7            # stop after 3 accepted steps each lowering the loss less than this
    lam0: float = 1e-3
    lam_max: float = 1e10
    max_reject: int = 16          # consecutive rejected steps before stopping (float32 noise floor)


@dataclass
class LMState:
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


def levenberg_marquardt(jtj_x, x0, lo, hi, opts: LMOptions | None = None, on_done=None, on_iter=None):
    """Minimise each row's loss from x0 (n, k).

    ``jtj_x(x (m, k), rows (m,)) -> (loss (m,), JTr (m, k), JTJ (m, k, k))`` in x space.
    ``on_done(rows, x, loss, status)`` is called after each iteration with the rows that
    finished in it (so their results can be written as they arrive)."""
    opts = opts or LMOptions()
    n, k = x0.shape
    x = np.clip(x0, lo, hi).astype(np.float64)
    L, g, H = jtj_x(x, np.arange(n))
    bad = ~np.isfinite(L)
    L[bad] = np.inf
    lam = np.full(n, opts.lam0)
    small = np.zeros(n, dtype=int)
    rejects = np.zeros(n, dtype=int)
    iters = np.zeros(n, dtype=int)
    nfev = np.ones(n, dtype=int)
    status = ["running"] * n
    running = np.ones(n, dtype=bool)
    g = np.where(np.isfinite(g), g, 0)
    H = np.where(np.isfinite(H), H, 0)
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
        if flat.any() and on_done:
            on_done(rows[flat], x, L, status)
        rows, trial = rows[~flat], trial[~flat]
        if rows.size == 0:
            continue
        Lt, gt, Ht = jtj_x(trial, rows)
        nfev[rows] += 1
        iters[rows] += 1
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
        if on_iter:
            on_iter(it, x, L, running)
        if done and on_done:
            on_done(np.array(done), x, L, status)
    last = np.flatnonzero(running)
    for i in last:
        status[i] = "iteration limit"
    if last.size and on_done:
        on_done(last, x, L, status)
    return LMState(x, L, iters, nfev, status)
