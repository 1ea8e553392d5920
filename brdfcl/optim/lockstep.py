"""Many nlopt optimisers in lockstep, their evaluations batched into one launch.

nlopt runs one problem at a time and calls back for each evaluation.  Here each
problem runs in its own thread; its objective posts the request and waits on its own
event.  When every running optimiser has posted one (the last to post wakes the
coordinator, and only it), the coordinator evaluates all of them together (one kernel
launch for the whole database) and sets each one's event.  Nothing wakes a thread that
has no answer yet: with one shared condition and notify_all, every request and answer
woke all ~400 threads (~310 us of host time per evaluation on an AMD EPYC).  Each
optimiser sees exactly the sequence it would see alone, so results are deterministic for a
given seed and independent of the batch.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import nlopt
import numpy as np

BIG = 1e300


@dataclass
class Problem:
    opt: nlopt.opt                 # configured optimiser (bounds, stopping); objective is set here
    x0: np.ndarray
    seed: int = 0


@dataclass
class Outcome:
    x: np.ndarray
    f: float
    status: int
    message: str
    nfev: int


_MESSAGES = {nlopt.SUCCESS: "success", nlopt.STOPVAL_REACHED: "stopval reached",
             nlopt.FTOL_REACHED: "ftol reached", nlopt.XTOL_REACHED: "xtol reached",
             nlopt.MAXEVAL_REACHED: "evaluation budget used", nlopt.MAXTIME_REACHED: "time budget used",
             nlopt.ROUNDOFF_LIMITED: "roundoff limited", nlopt.FORCED_STOP: "stopped"}


def run_lockstep(problems: list[Problem], evaluate) -> list[Outcome]:
    """Run every problem to completion.

    ``evaluate(xs (n, k), need_grad (n,) bool, ids (n,)) -> (f (n,), g (n, k))`` evaluates one
    batch; non-finite values are returned to nlopt as a huge loss so it steps away."""
    n = len(problems)
    cond = threading.Condition()          # the coordinator's: all requests are in
    answered = [threading.Event() for _ in range(n)]
    pending: dict[int, tuple] = {}
    results: dict[int, tuple] = {}
    active = set(range(n))
    outcomes: list[Outcome | None] = [None] * n
    failure: list[BaseException] = []
    nfev = [0] * n
    best = [(np.inf, None)] * n          # best point each optimiser has seen, kept whatever nlopt does

    def make_objective(i):
        def f(x, grad):
            if failure:   # stopped: nlopt (CRS2) may call again with ForcedStop still set; never block
                raise nlopt.ForcedStop
            with cond:
                pending[i] = (np.array(x), grad.size > 0)
                if len(pending) >= len(active):
                    cond.notify()
            answered[i].wait()
            answered[i].clear()
            with cond:
                val, g = results.pop(i)
            if val is None:
                raise nlopt.ForcedStop
            try:
                nfev[i] += 1
                if np.isfinite(val) and val < best[i][0]:
                    best[i] = (float(val), np.array(x))
                if grad.size:
                    grad[:] = g if np.isfinite(g).all() else 0.0
                return float(val) if np.isfinite(val) else BIG
            except Exception as e:  # a malformed answer: stop every optimiser and re-raise it after
                failure.append(e)
                raise nlopt.ForcedStop from None
        return f

    def worker(i):
        pr = problems[i]
        try:
            nlopt.srand(pr.seed)
            pr.opt.set_min_objective(make_objective(i))
            x0 = np.clip(pr.x0, pr.opt.get_lower_bounds(), pr.opt.get_upper_bounds())
            try:
                pr.opt.optimize(x0)
                status = pr.opt.last_optimize_result()
            except nlopt.RoundoffLimited:
                status = nlopt.ROUNDOFF_LIMITED
            except nlopt.ForcedStop:
                status = nlopt.FORCED_STOP
            except Exception as e:           # nlopt's own failure (e.g. its runtime_error)
                status = f"nlopt failure: {e or type(e).__name__}"
            fbest, xb = best[i]
            x = x0 if xb is None else xb
            outcomes[i] = Outcome(np.asarray(x), float(fbest), status if isinstance(status, int) else -1,
                                  _MESSAGES.get(status, str(status)), nfev[i])
        finally:
            with cond:
                active.discard(i)
                if len(pending) >= len(active):
                    cond.notify()

    threads = [threading.Thread(target=worker, args=(i,), daemon=True) for i in range(n)]
    for t in threads:
        t.start()
    while True:
        with cond:
            while active and len(pending) < len(active):
                cond.wait()
            if not active:
                break
            batch, pending = pending, {}
        ids = np.array(sorted(batch))
        xs = np.array([batch[i][0] for i in ids])
        need = np.array([batch[i][1] for i in ids])
        try:
            if failure:
                raise failure[0]
            f, g = evaluate(xs, need, ids)
            out = {int(i): (f[j], g[j]) for j, i in enumerate(ids)}
        except BaseException as e:          # stop every optimiser, then re-raise
            failure.append(e)
            out = {int(i): (None, None) for i in ids}
        with cond:
            results.update(out)
        for i in out:
            answered[i].set()
    for t in threads:
        t.join()
    if failure:
        raise failure[0]
    done = [o for o in outcomes if o is not None]
    if len(done) != n:
        raise RuntimeError(f"{n - len(done)} optimiser threads ended without an outcome")
    return done
