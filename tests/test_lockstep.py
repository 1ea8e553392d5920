"""brdfcl.optim.lockstep.run_lockstep on analytic functions (numpy and nlopt only, no OpenCL).

Every run goes through ``within``: a coordinator that deadlocks fails the test after a few
seconds instead of hanging the suite."""
import threading
import time

import nlopt
import numpy as np
import pytest

from brdfcl.optim.lockstep import BIG, DETERMINISTIC, Problem, run_lockstep

K = 3
LO, HI = np.full(K, -3.0), np.full(K, 3.0)


def within(seconds, fn, *args):
    box = {}

    def target():
        try:
            box["value"] = fn(*args)
        except BaseException as e:          # noqa: BLE001 - handed to the test
            box["error"] = e
    t = threading.Thread(target=target, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"run_lockstep did not return within {seconds} s"
    if "error" in box:
        raise box["error"]
    return box["value"]


def shifted_rosenbrock(c):
    """Rosenbrock in K dimensions moved so that its minimum (0) is at c."""
    def fg(x):
        y = np.asarray(x) - c + 1.0
        a, b = y[1:] - y[:-1] ** 2, 1.0 - y[:-1]
        f = float(np.sum(100.0 * a ** 2 + b ** 2))
        g = np.zeros(K)
        g[:-1] = -400.0 * y[:-1] * a - 2.0 * b
        g[1:] += 200.0 * a
        return f, g
    return fg


def mlsl_lds():
    opt = nlopt.opt(nlopt.G_MLSL_LDS, K)
    loc = nlopt.opt(nlopt.LD_LBFGS, K)
    loc.set_ftol_rel(1e-6)
    loc.set_maxeval(100)
    opt.set_local_optimizer(loc)
    return opt


ALGOS = {   # name: (constructor, gradient-based, evaluation budget)
    "LD_LBFGS": (lambda: nlopt.opt(nlopt.LD_LBFGS, K), True, 400),
    "LD_MMA": (lambda: nlopt.opt(nlopt.LD_MMA, K), True, 400),
    "LN_BOBYQA": (lambda: nlopt.opt(nlopt.LN_BOBYQA, K), False, 400),
    "LN_NELDERMEAD": (lambda: nlopt.opt(nlopt.LN_NELDERMEAD, K), False, 400),
    "GN_CRS2_LM": (lambda: nlopt.opt(nlopt.GN_CRS2_LM, K), False, 800),    # stochastic
    "GN_ISRES": (lambda: nlopt.opt(nlopt.GN_ISRES, K), False, 800),        # stochastic
    "G_MLSL_LDS": (mlsl_lds, None, 600),                                   # as fit.global_search
}


def make_opt(algo, lo=LO, hi=HI):
    ctor, _, budget = ALGOS[algo]
    opt = ctor()
    opt.set_lower_bounds(lo)
    opt.set_upper_bounds(hi)
    opt.set_maxeval(budget)
    opt.set_ftol_rel(1e-7)
    return opt


def run_alone(algo, fg, x0, seed):
    """nlopt directly on one problem, scored the way run_lockstep documents it: the best finite
    value seen, non-finite values handed to nlopt as BIG with a zero gradient."""
    opt = make_opt(algo)
    best, nfev = [np.inf, None], [0]

    def obj(x, grad):
        f, g = fg(x)
        nfev[0] += 1
        if np.isfinite(f) and f < best[0]:
            best[:] = [float(f), np.array(x)]
        if grad.size:
            grad[:] = g if np.isfinite(g).all() else 0.0
        return float(f) if np.isfinite(f) else BIG
    nlopt.srand(seed)
    opt.set_min_objective(obj)
    try:
        opt.optimize(x0)
        status = opt.last_optimize_result()
    except nlopt.RoundoffLimited:
        status = nlopt.ROUNDOFF_LIMITED
    return best[0], x0 if best[1] is None else best[1], nfev[0], status


class Evaluate:
    """The batched callback: row by row through each problem's own function; records batches."""

    def __init__(self, fgs):
        self.fgs = fgs
        self.batches = []

    def __call__(self, xs, need, ids):
        self.batches.append((np.array(ids), np.array(need)))
        assert len(set(ids.tolist())) == len(ids)
        f = np.empty(len(ids))
        g = np.empty((len(ids), xs.shape[1]))
        for j, i in enumerate(ids):
            f[j], g[j] = self.fgs[i](xs[j])
            if not need[j]:
                g[j] = np.nan                 # must be ignored where no gradient was asked for
        return f, g


def case(n, rng_seed=0):
    rng = np.random.default_rng(rng_seed)
    centres = rng.uniform(-1.5, 1.5, size=(n, K))
    x0s = rng.uniform(-2.5, 2.5, size=(n, K))
    return [shifted_rosenbrock(c) for c in centres], centres, x0s


def assert_same_as_alone(algos, fgs, x0s, seeds, outcomes):
    for i, (algo, fg, x0, seed, oc) in enumerate(zip(algos, fgs, x0s, seeds, outcomes)):
        f, x, nfev, status = run_alone(algo, fg, x0, seed)
        assert oc.nfev == nfev, (i, algo)
        assert oc.f == f, (i, algo, oc.f, f)                   # bitwise
        np.testing.assert_array_equal(oc.x, x, err_msg=f"problem {i} ({algo})")
        assert oc.status == status, (i, algo)


def deterministic(algo):
    return make_opt(algo).get_algorithm() in DETERMINISTIC


@pytest.mark.parametrize("algo,driver", [(a, d) for a in ALGOS for d in ("auto", "threads", "greenlets")
                                         if d != "greenlets" or deterministic(a)])
def test_each_problem_as_if_alone(algo, driver):
    """Four problems of one algorithm in lockstep end exactly (bitwise: same x, f, evaluations,
    status) where nlopt alone ends on each, with the same settings and seed, on either driver.
    Catches results handed to the wrong optimiser, a shared random state between threads (the
    stochastic algorithms), and a seed not applied."""
    fgs, centres, x0s = case(4)
    seeds = [11, 12, 13, 14]
    ev = Evaluate(fgs)
    out = within(30, run_lockstep, [Problem(make_opt(algo), x0, s) for x0, s in zip(x0s, seeds)], ev, driver)
    assert_same_as_alone([algo] * 4, fgs, x0s, seeds, out)
    for oc, fg in zip(out, fgs):
        assert oc.f == fg(oc.x)[0]                             # the reported point has that value
        assert (oc.x >= LO).all() and (oc.x <= HI).all()
    if algo in ("LD_LBFGS", "LN_BOBYQA"):                      # the local ones do converge here
        for oc, c in zip(out, centres):
            np.testing.assert_allclose(oc.x, c, atol=1e-3)


class CountThreads(Evaluate):
    """Evaluate that records the number of live threads at each call."""

    def __call__(self, xs, need, ids):
        self.threads = max(getattr(self, "threads", 0), threading.active_count())
        return super().__call__(xs, need, ids)


@pytest.mark.parametrize("algos,driver", [(["LD_LBFGS", "LN_BOBYQA", "LD_MMA", "LN_NELDERMEAD"], "greenlets"),
                                          (["LD_LBFGS", "GN_CRS2_LM"], "threads")])
def test_auto_driver_threads_only_for_random_algorithms(algos, driver):
    """``auto`` runs deterministic algorithms on greenlets in the caller's thread (no thread per
    optimiser: threads cost host time per evaluation) and any batch with a random one on threads."""
    fgs, _, x0s = case(len(algos))
    ev = CountThreads(fgs)
    before = threading.active_count()
    within(30, run_lockstep, [Problem(make_opt(a), x0, 1) for a, x0 in zip(algos, x0s)], ev)
    assert ev.threads - before == (1 if driver == "greenlets" else 1 + len(algos))   # 1: within's own


def test_unknown_driver_is_refused():
    with pytest.raises(ValueError, match="lockstep driver 'fibres'"):
        run_lockstep([], Evaluate([]), "fibres")


def test_seed_matters_for_stochastic_algorithms():
    """Guards the test above from passing vacuously: CRS2 does depend on the seed."""
    fg = case(1)[0][0]
    x0 = np.zeros(K)
    a, b = run_alone("GN_CRS2_LM", fg, x0, 1), run_alone("GN_CRS2_LM", fg, x0, 2)
    assert (a[0], a[2]) != (b[0], b[2])
    assert run_alone("GN_CRS2_LM", fg, x0, 1)[:1] == a[:1]


def test_mixed_algorithms_batched_with_need_flags():
    """One problem per local algorithm plus CRS2 in one run: requests are batched (the first batch
    holds every problem, one evaluate call per round, never one per request), ``need`` is true
    exactly for the gradient-based ones, and each still ends as it does alone."""
    algos = ["LD_LBFGS", "LN_BOBYQA", "LD_MMA", "LN_NELDERMEAD", "GN_CRS2_LM", "GN_ISRES"]
    fgs, _, x0s = case(len(algos), 1)
    seeds = list(range(len(algos)))
    ev = Evaluate(fgs)
    out = within(30, run_lockstep, [Problem(make_opt(a), x0, s) for a, x0, s in zip(algos, x0s, seeds)],
                 ev)
    assert_same_as_alone(algos, fgs, x0s, seeds, out)
    ids0, _ = ev.batches[0]
    assert ids0.tolist() == list(range(len(algos)))
    assert len(ev.batches) == max(oc.nfev for oc in out)       # every running optimiser, every round
    assert sum(len(ids) for ids, _ in ev.batches) == sum(oc.nfev for oc in out)
    for ids, need in ev.batches:
        assert list(ids) == sorted(ids)
        np.testing.assert_array_equal(need, [ALGOS[algos[i]][1] for i in ids])
    assert sum(len(ids) > 1 for ids, _ in ev.batches) >= min(oc.nfev for oc in out)


def nan_where(fg, region, grad_only=False):
    """fg with NaN (value and gradient, or the gradient alone) where region(x); counts the NaNs."""
    def h(x):
        if region(x):
            h.hits += 1
            return (fg(x)[0] if grad_only else np.nan), np.full(K, np.nan)
        return fg(x)
    h.hits = 0
    return h


def test_nan_problems_do_not_disturb_the_others():
    """NaN everywhere, NaN over part of the box, a NaN gradient: every problem finishes, each
    exactly as nlopt alone when handed BIG for a non-finite value and a zero gradient; the
    NaN-everywhere one reports f = inf at its start, never NaN.  Catches NaN passed to nlopt
    (CRS2 then ranks its population differently, LBFGS steps to NaN) and NaN in the results."""
    fgs, _, x0s = case(5, 2)
    fgs[1] = nan_where(fgs[1], lambda x: True)
    fgs[2] = nan_where(fgs[2], lambda x: x[0] > 1.0)
    fgs[3] = nan_where(fgs[3], lambda x: x[1] < -1.0)
    fgs[4] = nan_where(fgs[4], lambda x: x[0] > 0.5, grad_only=True)
    x0s[2, 0], x0s[3, 1], x0s[4, 0] = 0.0, 0.0, 1.0
    algos = ["LN_BOBYQA", "LN_BOBYQA", "GN_CRS2_LM", "LN_NELDERMEAD", "LD_LBFGS"]
    seeds = [5, 6, 7, 8, 9]
    out = within(30, run_lockstep, [Problem(make_opt(a), x0, s) for a, x0, s in zip(algos, x0s, seeds)],
                 Evaluate(fgs))
    assert all(fgs[i].hits > 0 for i in range(1, 5))          # the NaN regions were visited
    assert out[1].f == np.inf
    np.testing.assert_array_equal(out[1].x, x0s[1])
    assert out[2].x[0] <= 1.0 and out[3].x[1] >= -1.0
    assert not any(np.isnan(oc.f) or np.isnan(oc.x).any() for oc in out)
    assert_same_as_alone(algos, fgs, x0s, seeds, out)


def test_start_outside_the_box_is_clipped():
    """nlopt refuses a start outside its bounds; run_lockstep starts from the clipped point."""
    fgs, _, _ = case(2, 6)
    x0s = np.array([[-9.0, 0.0, 9.0], [0.5, 4.0, -0.5]])
    ev = Evaluate(fgs)
    out = within(30, run_lockstep, [Problem(make_opt("LN_BOBYQA"), x0, 1) for x0 in x0s], ev)
    clipped = np.clip(x0s, LO, HI)
    assert not any(oc.message.startswith("nlopt failure") for oc in out)
    assert_same_as_alone(["LN_BOBYQA"] * 2, fgs, clipped, [1, 1], out)


def test_failing_optimiser_does_not_hang_the_others():
    """nlopt itself refuses one problem (lower bound above upper bound): it reports the failure
    and the others run to the end they reach alone."""
    fgs, _, x0s = case(3, 3)
    bad = make_opt("LN_BOBYQA", lo=np.full(K, 1.0), hi=np.full(K, -1.0))
    problems = [Problem(make_opt("LN_BOBYQA"), x0s[0], 1), Problem(bad, x0s[1], 2),
                Problem(make_opt("LD_LBFGS"), x0s[2], 3)]
    out = within(30, run_lockstep, problems, Evaluate(fgs))
    assert out[1].status < 0 and out[1].message.startswith("nlopt failure")
    assert out[1].nfev == 0 and out[1].f == np.inf
    assert_same_as_alone(["LN_BOBYQA", "LD_LBFGS"], [fgs[0], fgs[2]], x0s[[0, 2]], [1, 3], [out[0], out[2]])


@pytest.mark.parametrize("at_call,algos", [
    (1, ["LD_LBFGS", "LN_BOBYQA", "GN_CRS2_LM", "LN_NELDERMEAD", "LD_MMA"]),
    (4, ["LD_LBFGS", "LN_BOBYQA", "GN_CRS2_LM", "LN_NELDERMEAD", "LD_MMA"]),
    (4, ["LD_LBFGS", "LN_BOBYQA", "LD_LBFGS", "LN_NELDERMEAD", "LD_MMA"])])      # on greenlets
def test_raising_evaluate_stops_everyone_and_reraises(at_call, algos):
    """An exception from the batched evaluation (e.g. a failed launch) reaches the caller promptly,
    with every optimiser stopped (and every thread ended)."""
    fgs, _, x0s = case(5, 4)
    calls = [0]

    def evaluate(xs, need, ids):
        calls[0] += 1
        if calls[0] == at_call:
            raise RuntimeError("launch failed")
        return Evaluate(fgs)(xs, need, ids)
    before = threading.active_count()
    problems = [Problem(make_opt(a), x0, i) for i, (a, x0) in enumerate(zip(algos, x0s))]
    with pytest.raises(RuntimeError, match="launch failed"):
        within(10, run_lockstep, problems, evaluate)
    assert calls[0] == at_call                                  # nothing evaluated after the failure
    deadline = time.monotonic() + 5
    while threading.active_count() > before and time.monotonic() < deadline:
        time.sleep(0.01)
    assert threading.active_count() == before


def test_error_outside_an_objective_on_greenlets_stops_the_others():
    """A problem that fails before nlopt runs it (a start of the wrong shape) raises to the caller;
    the optimisers already waiting in their objectives are stopped (each then ends, its optimiser
    usable again), not left suspended."""
    fgs, _, x0s = case(3, 7)
    opts = [make_opt("LD_LBFGS") for _ in range(3)]
    problems = [Problem(opts[0], x0s[0], 1), Problem(opts[1], x0s[1], 2), Problem(opts[2], np.zeros(K + 2), 3)]
    with pytest.raises(ValueError):
        within(10, run_lockstep, problems, Evaluate(fgs), "greenlets")
    out = within(10, run_lockstep, [Problem(opts[0], x0s[0], 1)], Evaluate(fgs[:1]))
    assert_same_as_alone(["LD_LBFGS"], fgs[:1], x0s[:1], [1], out)


@pytest.mark.parametrize("algo", ["GN_CRS2_LM", "LD_LBFGS"])
def test_malformed_evaluation_stops_everyone_and_reraises(algo):
    """An answer of the wrong shape fails inside an optimiser's objective; with CRS2 (which keeps
    calling after a stop) that used to leave the lock held and hang.  LBFGS: the same on greenlets."""
    fgs, _, x0s = case(3, 5)

    def evaluate(xs, need, ids):
        f, g = Evaluate(fgs)(xs, need, ids)
        return np.stack([f, f], axis=1), g                     # (n, 2) instead of (n,)
    problems = [Problem(make_opt(algo), x0, i) for i, x0 in enumerate(x0s)]
    with pytest.raises(ValueError):
        within(10, run_lockstep, problems, evaluate)


@pytest.mark.parametrize("driver", ["greenlets", "threads"])
def test_many_problems_finish(driver):
    """200 problems in one run: all at their own optimum, the first batch holds all 200."""
    n = 200
    rng = np.random.default_rng(5)
    centres = rng.uniform(-2, 2, size=(n, K))

    def quad(c):
        return lambda x: (float(np.sum((x - c) ** 2)), 2 * (x - c))
    ev = Evaluate([quad(c) for c in centres])
    problems = [Problem(make_opt("LD_LBFGS" if i % 2 else "LN_BOBYQA"), np.zeros(K), i) for i in range(n)]
    t0 = time.perf_counter()
    out = within(60, run_lockstep, problems, ev, driver)
    assert time.perf_counter() - t0 < 30
    assert len(out) == n and all(oc is not None for oc in out)
    assert len(ev.batches[0][0]) == n
    np.testing.assert_allclose(np.array([oc.x for oc in out]), centres, atol=1e-4)
    assert len(ev.batches) == max(oc.nfev for oc in out)


def test_empty_list():
    assert within(5, run_lockstep, [], Evaluate([])) == []
