"""Many nlopt optimisers in lockstep, their evaluations batched into one launch.

nlopt runs one problem at a time and calls back for each evaluation.  Here each problem's
optimiser is suspended inside its objective while its request waits; when every running
optimiser has posted one, the coordinator evaluates all of them together (one kernel launch for
the whole database) and resumes each with its answer.  Each optimiser sees exactly the sequence
it would see alone, so results are deterministic for a given seed and independent of the batch.

Two ways to suspend an optimiser (``run_lockstep``'s ``driver``):
* ``greenlets``: every optimiser on its own greenlet in the caller's thread; a request is a
  switch back to the coordinator (a few microseconds).  Only for algorithms that draw no random
  numbers (`DETERMINISTIC`): nlopt's random state is per thread, and greenlets share one.
* ``threads``: every optimiser in its own thread with its own random state (nlopt.srand of its
  seed), waiting on its own event; the last to post wakes the coordinator, and only it.  Hundreds
  of threads handing over the GIL cost several times the host time per evaluation that greenlets
  do, enough to outweigh the kernels of a global search: ``auto`` takes greenlets wherever the
  algorithms allow.
"""
from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

import greenlet
import nlopt
import numpy as np

BIG = 1e300

# nlopt algorithms that never call nlopt's random number generator: safe to interleave in one thread.
DETERMINISTIC = frozenset({nlopt.LD_LBFGS, nlopt.LD_MMA, nlopt.LN_BOBYQA, nlopt.LN_NELDERMEAD})
DRIVERS = ("auto", "greenlets", "threads")


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

Ask = Callable[[np.ndarray, bool], tuple]       # post (x, need_grad), wait: (value, gradient) or (None, None)


class _Run:
    """What both drivers share: each optimiser's objective (its bookkeeping of evaluations and of
    the best point seen, kept whatever nlopt does), its outcome, and the batched evaluation."""

    def __init__(self, problems: list[Problem], evaluate):
        self.problems, self.evaluate = problems, evaluate
        n = len(problems)
        self.nfev = [0] * n
        self.best: list[tuple[float, np.ndarray | None]] = [(np.inf, None)] * n
        self.failure: list[BaseException] = []

    def _objective(self, i: int, ask: Ask):
        def f(x, grad):
            if self.failure:  # stopped: nlopt (CRS2) may call again with ForcedStop still set; never block
                raise nlopt.ForcedStop
            val, g = ask(np.array(x), grad.size > 0)
            if val is None:
                raise nlopt.ForcedStop
            try:
                self.nfev[i] += 1
                if np.isfinite(val) and val < self.best[i][0]:
                    self.best[i] = (float(val), np.array(x))
                if grad.size:
                    grad[:] = g if np.isfinite(g).all() else 0.0
                return float(val) if np.isfinite(val) else BIG
            except Exception as e:  # a malformed answer: stop every optimiser and re-raise it after
                self.failure.append(e)
                raise nlopt.ForcedStop from None
        return f

    def solve(self, i: int, ask: Ask) -> Outcome:
        """Problem i run to its end, each evaluation requested through ``ask``."""
        pr = self.problems[i]
        nlopt.srand(pr.seed)
        pr.opt.set_min_objective(self._objective(i, ask))
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
        fbest, xb = self.best[i]
        return Outcome(np.asarray(x0 if xb is None else xb), float(fbest), status if isinstance(status, int) else -1,
                       _MESSAGES.get(status, str(status)), self.nfev[i])

    def answer(self, batch: dict[int, tuple[np.ndarray, bool]]) -> dict[int, tuple]:
        """One batched evaluation of the requests ``batch`` (id: (x, need_grad)); after a failure
        every answer is (None, None), which stops the optimiser that receives it."""
        ids = np.array(sorted(batch))
        try:
            if self.failure:
                raise self.failure[0]
            f, g = self.evaluate(np.array([batch[i][0] for i in ids]), np.array([batch[i][1] for i in ids]), ids)
            return {int(i): (f[j], g[j]) for j, i in enumerate(ids)}
        except BaseException as e:          # stop every optimiser, then re-raise
            if not self.failure:
                self.failure.append(e)
            return {int(i): (None, None) for i in ids}


def run_lockstep(problems: list[Problem], evaluate, driver: str = "auto") -> list[Outcome]:
    """Run every problem to completion.

    ``evaluate(xs (n, k), need_grad (n,) bool, ids (n,)) -> (f (n,), g (n, k))`` evaluates one
    batch; non-finite values are returned to nlopt as a huge loss so it steps away.  ``driver``:
    see the module's docstring; ``auto`` takes greenlets when every algorithm is `DETERMINISTIC`."""
    if driver not in DRIVERS:
        raise ValueError(f"lockstep driver '{driver}'; valid: {', '.join(DRIVERS)}")
    if driver == "auto":
        driver = "greenlets" if all(p.opt.get_algorithm() in DETERMINISTIC for p in problems) else "threads"
    run = _Run(problems, evaluate)
    outcomes = (_on_greenlets if driver == "greenlets" else _on_threads)(run)
    if run.failure:
        raise run.failure[0]
    done = [o for o in outcomes if o is not None]
    if len(done) != len(problems):
        raise RuntimeError(f"{len(problems) - len(done)} optimisers ended without an outcome")
    return done


def _on_greenlets(run: _Run) -> list[Outcome | None]:
    coordinator = greenlet.getcurrent()

    def ask(x: np.ndarray, need: bool) -> tuple:
        return coordinator.switch((x, need))

    n = len(run.problems)
    lets = [greenlet.greenlet(lambda i=i: run.solve(i, ask)) for i in range(n)]
    outcomes: list[Outcome | None] = [None] * n
    answers: dict[int, tuple] = {i: () for i in range(n)}       # () starts a greenlet
    try:
        while answers:
            batch = {}
            for i, a in answers.items():
                got = lets[i].switch(*a) if a else lets[i].switch()
                if lets[i].dead:
                    outcomes[i] = got
                else:
                    batch[i] = got
            answers = {i: (a,) for i, a in run.answer(batch).items()} if batch else {}
    except BaseException as e:      # escaped a solve (or an interrupt): stop the suspended ones, re-raise
        if not run.failure:
            run.failure.append(e)
        for let in lets:
            if let and not let.dead:                    # started and waiting in its objective
                let.switch((None, None))
        raise
    return outcomes


def _on_threads(run: _Run) -> list[Outcome | None]:
    n = len(run.problems)
    cond = threading.Condition()          # the coordinator's: all requests are in
    answered = [threading.Event() for _ in range(n)]
    pending: dict[int, tuple] = {}
    results: dict[int, tuple] = {}
    active = set(range(n))
    outcomes: list[Outcome | None] = [None] * n

    def asker(i: int) -> Ask:
        def ask(x: np.ndarray, need: bool) -> tuple:
            with cond:
                pending[i] = (x, need)
                if len(pending) >= len(active):
                    cond.notify()
            answered[i].wait()
            answered[i].clear()
            with cond:
                return results.pop(i)
        return ask

    def worker(i: int) -> None:
        try:
            outcomes[i] = run.solve(i, asker(i))
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
        out = run.answer(batch)
        with cond:
            results.update(out)
        for i in out:
            answered[i].set()
    for t in threads:
        t.join()
    return outcomes
