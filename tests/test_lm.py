"""brdfcl.optim.lm.levenberg_marquardt on problems with known answers (numpy only, no OpenCL).

The callback convention is the kernels': loss = sum r^2, JTr = J^T r, JTJ = J^T J, for the
rows of the batch that are asked for."""
import numpy as np
import pytest
from scipy.optimize import lsq_linear

from brdfcl.optim.lm import LMOptions, LMRun, levenberg_marquardt
from brdfcl.optim.status import Status

FLAT = Status.PREDICTED_FTOL
FTOL = Status.FTOL
STUCK = Status.NO_DECREASE
LIMIT = Status.ITERATION_LIMIT


def linear(A, b):
    A, b = np.asarray(A, float), np.asarray(b, float)
    return lambda x: (A @ x - b, A)


def rosenbrock(x):
    """Rosenbrock's function as least squares: minimum 0 at (1, 1)."""
    return np.array([10 * (x[1] - x[0] ** 2), 1 - x[0]]), np.array([[-20 * x[0], 10.0], [-1.0, 0.0]])


class Batch:
    """jtj_x over one residual function per row; records every call."""

    def __init__(self, residuals, lo=None, hi=None):
        self.residuals = residuals
        self.lo, self.hi = lo, hi
        self.calls = []

    def __call__(self, x, rows):
        x = np.array(x)
        assert x.shape == (rows.size, x.shape[1])
        if self.lo is not None:       # trial points are always inside the box
            assert (x >= self.lo).all() and (x <= self.hi).all()
        self.calls.append((np.array(rows), x))
        L, g, H = [], [], []
        for xi, i in zip(x, rows):
            r, J = self.residuals[i](xi)
            L.append(r @ r)
            g.append(J.T @ r)
            H.append(J.T @ J)
        return np.array(L), np.array(g), np.array(H)


def loss_at(res, x):
    r, _ = res(x)
    return r @ r


def test_linear_least_squares_is_one_gauss_newton_step():
    """Undamped (lam0=0): the first step lands on numpy's lstsq solution and the next iteration
    stops on the predicted decrease.  Catches a wrong step sign, a step not solving (H + lam D) d
    = -g, or a decrement test that never fires on a solved problem."""
    rng = np.random.default_rng(1)
    A, b = rng.normal(size=(12, 4)), rng.normal(size=12)
    res = linear(A, b)
    lo, hi = np.full(4, -1e3), np.full(4, 1e3)
    st = levenberg_marquardt(Batch([res]), np.zeros((1, 4)), lo, hi, LMOptions(lam0=0.0))
    xs = np.linalg.lstsq(A, b, rcond=None)[0]
    np.testing.assert_allclose(st.x[0], xs, rtol=1e-12, atol=1e-12)
    assert st.loss[0] == pytest.approx(loss_at(res, xs), rel=1e-12)
    assert st.status == [FLAT]
    assert st.iters[0] == 1 and st.nfev[0] == 2


def test_linear_least_squares_damped():
    """Default options: stops when an undamped step would gain < ftol of the loss.  For a linear
    problem that prediction is exact, so the loss ends within ftol (relative) of the optimum; the
    point itself is only ~sqrt(ftol) close, a tighter ftol gets it to rounding."""
    rng = np.random.default_rng(2)
    A, b = rng.normal(size=(20, 5)), rng.normal(size=20)
    res = linear(A, b)
    xs = np.linalg.lstsq(A, b, rcond=None)[0]
    lo, hi = np.full(5, -1e3), np.full(5, 1e3)
    x0 = rng.normal(size=(1, 5))
    st = levenberg_marquardt(Batch([res]), x0, lo, hi)
    assert st.status == [FLAT]
    assert loss_at(res, xs) <= st.loss[0] <= loss_at(res, xs) + 1e-7 * st.loss[0]
    assert 2 <= st.iters[0] <= 10
    st = levenberg_marquardt(Batch([res]), x0, lo, hi, LMOptions(ftol=1e-30))
    np.testing.assert_allclose(st.x[0], xs, rtol=1e-10, atol=1e-12)


def test_rosenbrock_converges_to_one_one():
    lo, hi = np.full(2, -5.0), np.full(2, 5.0)
    st = levenberg_marquardt(Batch([rosenbrock]), np.array([[-1.2, 1.0]]), lo, hi,
                             LMOptions(max_iter=200))
    np.testing.assert_allclose(st.x[0], [1.0, 1.0], atol=1e-8)
    assert st.loss[0] < 1e-16
    assert st.status[0].converged, st.status
    assert st.iters[0] < 100


def projected_gradient_optimal(g, x, lo, hi, tol):
    """KKT for a box: free components have zero gradient, bound ones point outwards."""
    at_lo, at_hi = x <= lo, x >= hi
    free = ~(at_lo | at_hi)
    return (np.abs(g[free]) <= tol).all() and (g[at_lo] >= -tol).all() and (g[at_hi] <= tol).all()


def test_bounded_linear_matches_bvls():
    """Optimum with active bounds: same point as scipy's exact bounded solver, on the bound exactly,
    projected-gradient optimal.  Catches an active set with the wrong sign (a bound that stalls
    the step or one that is never let go) and steps leaving the box."""
    rng = np.random.default_rng(3)
    A, b = rng.normal(size=(15, 4)), 3 * rng.normal(size=15)
    lo, hi = np.full(4, -0.3), np.full(4, 0.3)
    ref = lsq_linear(A, b, bounds=(lo, hi), method="bvls", tol=1e-14)
    assert ((ref.x <= lo) | (ref.x >= hi)).any()                 # the test needs an active bound
    cb = Batch([linear(A, b)], lo, hi)
    st = levenberg_marquardt(cb, np.zeros((1, 4)), lo, hi, LMOptions(max_iter=100, ftol=1e-30))
    x = st.x[0]
    np.testing.assert_allclose(x, ref.x, atol=1e-8)
    assert ((x >= lo) & (x <= hi)).all()
    bound = (ref.x <= lo) | (ref.x >= hi)
    np.testing.assert_array_equal(x[bound], ref.x[bound])        # on the bound, not near it
    g = A.T @ (A @ x - b)
    assert projected_gradient_optimal(g, x, lo, hi, 1e-8 * np.abs(A.T @ b).max())
    assert st.status[0].converged


def test_rosenbrock_with_optimum_on_upper_bound():
    """x0 <= 0.5 moves Rosenbrock's minimum to (0.5, 0.25), where d/dx0 pushes outwards."""
    lo, hi = np.array([-2.0, -2.0]), np.array([0.5, 2.0])
    st = levenberg_marquardt(Batch([rosenbrock], lo, hi), np.array([[-1.2, 1.0]]), lo, hi,
                             LMOptions(max_iter=200, ftol=1e-30))
    x = st.x[0]
    assert x[0] == 0.5
    assert x[1] == pytest.approx(0.25, abs=1e-9)
    r, J = rosenbrock(x)
    g = J.T @ r
    assert g[0] < -0.1                                           # held by the bound
    assert projected_gradient_optimal(g, x, lo, hi, 1e-8)
    assert st.status[0].converged


def test_start_outside_box_is_clipped():
    lo, hi = np.zeros(2), np.ones(2)
    cb = Batch([linear(np.eye(2), [0.5, 2.0])], lo, hi)
    st = levenberg_marquardt(cb, np.array([[-3.0, 7.0]]), lo, hi, LMOptions(ftol=1e-30))
    np.testing.assert_array_equal(cb.calls[0][1], [[0.0, 1.0]])
    np.testing.assert_allclose(st.x[0], [0.5, 1.0], atol=1e-10)


def test_batch_rows_finish_at_different_iterations():
    """Rows with different problems in one batch: each one's answer is what it gets alone,
    finished rows are no longer evaluated, ``on_done`` reports each row once with its final
    point and status, and ``on_iter`` sees a running mask that only ever switches off."""
    rng = np.random.default_rng(4)
    A, b = rng.normal(size=(10, 2)), rng.normal(size=10)
    xs = np.linalg.lstsq(A, b, rcond=None)[0]
    residuals = [linear(A, b), rosenbrock, linear(A, b), rosenbrock]
    x0 = np.array([xs, [-1.2, 1.0], [3.0, -2.0], [0.0, 0.0]])
    lo, hi = np.full(2, -5.0), np.full(2, 5.0)
    opts = LMOptions(max_iter=200, ftol=1e-30)
    done, masks = {}, []

    def on_done(rows, x, L, status):
        assert len(rows)
        for i in rows:
            assert i not in done, f"row {i} reported twice"
            assert status[i] != "running"
            done[int(i)] = (x[i].copy(), float(L[i]), status[i])

    def on_iter(it, x, L, running):
        assert it == len(masks)
        masks.append(running.copy())
        assert not running[list(done)].any()                     # reported rows are not running

    cb = Batch(residuals, lo, hi)
    st = levenberg_marquardt(cb, x0, lo, hi, opts, on_done=on_done, on_iter=on_iter)

    # every row reported once, with what the result says
    assert sorted(done) == [0, 1, 2, 3]
    for i, (x, L, s) in done.items():
        np.testing.assert_array_equal(x, st.x[i])
        assert L == st.loss[i] and s == st.status[i]
    # the answers
    np.testing.assert_allclose(st.x[[0, 2]], [xs, xs], atol=1e-8)
    np.testing.assert_allclose(st.x[[1, 3]], np.ones((2, 2)), atol=1e-8)
    assert st.status[0] == FLAT and st.iters[0] == 0            # started at its optimum
    assert len(set(st.iters.tolist())) >= 3                      # rows finished at different times
    # each row matches the same row run alone (rows do not interact)
    for i in range(4):
        alone = levenberg_marquardt(Batch([residuals[i]]), x0[i:i + 1], lo, hi, opts)
        np.testing.assert_array_equal(alone.x[0], st.x[i])
        assert alone.iters[0] == st.iters[i] and alone.status[0] == st.status[i]
    # the mask only switches off, and a row is evaluated only while it runs
    M = np.array(masks)
    assert (M[1:] <= M[:-1]).all()
    assert len(cb.calls) == 1 + len(masks)                       # one launch per iteration
    for it, (rows, _) in enumerate(cb.calls[1:]):
        before = set(np.flatnonzero(M[it - 1])) if it else {0, 1, 2, 3}
        assert set(np.flatnonzero(M[it])) <= set(rows.tolist()) <= before
    evaluated = np.zeros(4, int)
    for rows, _ in cb.calls[1:]:
        evaluated[rows] += 1
    np.testing.assert_array_equal(evaluated, st.iters)
    np.testing.assert_array_equal(st.nfev, st.iters + 1)


def test_nonfinite_trial_loss_is_rejected():
    """The callback returns NaN beyond x = 1; the minimum of (x - 2)^2 is out there, so LM must
    back off to finite points and never accept NaN."""
    def res(x):
        if x[0] > 1.0:
            return np.array([np.nan]), np.array([[np.nan]])
        return np.array([x[0] - 2.0]), np.array([[1.0]])
    lo, hi = np.array([-10.0]), np.array([10.0])
    cb = Batch([res])
    st = levenberg_marquardt(cb, np.array([[0.0]]), lo, hi)
    assert any(c[1][0, 0] > 1.0 for c in cb.calls)             # NaN was returned, and refused
    assert np.isfinite(st.x).all() and np.isfinite(st.loss).all()
    assert 0.999 < st.x[0, 0] <= 1.0
    assert st.loss[0] == loss_at(res, st.x[0])
    assert st.status[0] != Status.RUNNING


def test_nonfinite_gradient_is_rejected():
    """Finite loss but NaN J^T J beyond x = 1: still a rejected step."""
    def res(x):
        return np.array([x[0] - 2.0]), np.array([[1.0 if x[0] <= 1.0 else np.nan]])
    st = levenberg_marquardt(Batch([res]), np.array([[0.0]]), np.array([-10.0]), np.array([10.0]))
    assert np.isfinite(st.x).all() and st.x[0, 0] <= 1.0


def test_nonfinite_start_gives_inf_not_nan():
    """A row whose start evaluates to NaN ends with loss inf (never NaN) and does not disturb
    the other rows."""
    bad = lambda x: (np.array([np.nan]), np.array([[np.nan]]))   # noqa: E731
    good = linear([[1.0]], [0.25])
    lo, hi = np.array([-1.0]), np.array([1.0])
    st = levenberg_marquardt(Batch([bad, good]), np.array([[0.5], [0.5]]), lo, hi)
    assert st.loss[0] == np.inf and not np.isnan(st.x).any()
    assert st.status[0] != Status.RUNNING
    assert st.x[1, 0] == pytest.approx(0.25, abs=1e-10)


def test_stop_on_small_accepted_decrements():
    """Heavy damping makes every accepted step lower the loss by < ftol relative: three in a row
    stop with 'converged (ftol)'.  Catches a counter that is not counted or not reset."""
    A, b = np.eye(2), np.array([1.0, 2.0])
    lo, hi = np.full(2, -10.0), np.full(2, 10.0)
    st = levenberg_marquardt(Batch([linear(A, b)]), np.zeros((1, 2)), lo, hi, LMOptions(lam0=1e9))
    assert st.status == [FTOL]
    assert st.iters[0] == 3
    # a tolerance below the decrements does not stop it there
    st = levenberg_marquardt(Batch([linear(A, b)]), np.zeros((1, 2)), lo, hi,
                             LMOptions(lam0=1e9, ftol=1e-12))
    assert st.iters[0] > 3 and st.status[0] != FTOL


def uphill():
    """Reports the gradient with the wrong sign: every step goes uphill and is rejected."""
    def cb(x, rows):
        r = x - 2.0
        return (r ** 2).sum(1), -r, np.tile(np.eye(x.shape[1]), (len(rows), 1, 1))
    return cb


@pytest.mark.parametrize("max_reject", [16, 5])
def test_stop_on_rejected_step_limit(max_reject):
    x0 = np.zeros((1, 2))
    st = levenberg_marquardt(uphill(), x0, np.full(2, -10.0), np.full(2, 10.0),
                             LMOptions(max_reject=max_reject))
    assert st.status == [STUCK]
    assert st.iters[0] == max_reject
    np.testing.assert_array_equal(st.x, x0)                      # never moved
    assert st.loss[0] == 8.0


def test_stop_on_damping_limit():
    """lam 1 -> 4 -> 16 -> 64 -> 256 > lam_max = 100: stops after the fourth rejection."""
    st = levenberg_marquardt(uphill(), np.zeros((1, 2)), np.full(2, -10.0), np.full(2, 10.0),
                             LMOptions(lam0=1.0, lam_max=100.0))
    assert st.status == [STUCK] and st.iters[0] == 4


def test_iteration_limit():
    reported = []
    st = levenberg_marquardt(Batch([rosenbrock]), np.array([[-1.2, 1.0]]), np.full(2, -5.0),
                             np.full(2, 5.0), LMOptions(max_iter=3),
                             on_done=lambda rows, x, L, s: reported.append((list(rows), s[rows[0]])))
    assert st.status == [LIMIT]
    assert st.iters[0] == 3 and st.nfev[0] == 4
    assert reported == [([0], LIMIT)]


def scripted(losses):
    """A one-row callback returning the given losses in order (the first for the start), with
    g = 1 and H = 1 so that the predicted decrease never stops it."""
    it = iter(losses)

    def cb(x, rows):
        assert rows.tolist() == [0]
        return np.array([next(it)]), np.ones((1, 1)), np.ones((1, 1, 1))
    return cb


def run_scripted(losses, **kw):
    return levenberg_marquardt(scripted(losses), np.zeros((1, 1)), np.array([-1e9]), np.array([1e9]),
                               LMOptions(**kw))


def test_small_decrements_must_be_consecutive():
    """small, small, big, small, small, small: stops at the sixth step, not the fourth."""
    st = run_scripted([1.0, 1 - 1e-9, 1 - 2e-9, 0.5, 0.5 - 1e-9, 0.5 - 2e-9, 0.5 - 3e-9, 0.1])
    assert st.status == [FTOL] and st.iters[0] == 6 and st.loss[0] == 0.5 - 3e-9


def test_rejections_must_be_consecutive():
    """max_reject=2 with reject, accept, reject, accept, reject, reject: stops at the sixth."""
    st = run_scripted([1.0, 2.0, 0.9, 2.0, 0.8, 2.0, 2.0, 0.1], max_reject=2)
    assert st.status == [STUCK] and st.iters[0] == 6 and st.loss[0] == 0.8


def test_equal_loss_is_not_accepted():
    """Only a lower loss is accepted: a trial that ties is a rejection and x stays put."""
    st = run_scripted([1.0] * 20, max_reject=5)
    assert st.status == [STUCK] and st.iters[0] == 5
    assert st.x[0, 0] == 0.0


def test_negative_infinite_loss_is_rejected():
    st = run_scripted([1.0, -np.inf, np.nan, 0.5, -np.inf, np.inf, 0.25] + [0.25] * 20, max_reject=4)
    assert st.loss[0] == 0.25 and np.isfinite(st.x).all()


def test_run_steps_report_each_row_once_as_the_callbacks_do():
    """LMRun.steps (what the fit iterates) finishes every row exactly once, at the moment
    levenberg_marquardt's on_done reports it, with the same final state; a row finishing before a
    launch (at its optimum) comes in a step without evaluations."""
    rng = np.random.default_rng(6)
    A, b = rng.normal(size=(10, 2)), rng.normal(size=10)
    xs = np.linalg.lstsq(A, b, rcond=None)[0]
    residuals = [linear(A, b), rosenbrock, rosenbrock]
    x0 = np.array([xs, [-1.2, 1.0], [0.0, 0.0]])
    lo, hi = np.full(2, -5.0), np.full(2, 5.0)
    opts = LMOptions(max_iter=30)
    reported = []
    ref = levenberg_marquardt(Batch(residuals, lo, hi), x0, lo, hi, opts,
                              on_done=lambda rows, x, L, s: reported.append(sorted(rows.tolist())))
    run = LMRun(Batch(residuals, lo, hi), x0, lo, hi, opts)
    steps = [(s.iteration, s.evaluated, sorted(s.finished.tolist()), s.running.copy()) for s in run.steps()]
    assert [f for _, _, f, _ in steps if f] == reported
    assert sorted(sum(reported, [])) == [0, 1, 2]
    assert steps[0][:3] == (0, False, [0])                        # row 0 starts at its optimum
    assert not steps[-1][3].any()
    np.testing.assert_array_equal(run.state.x, ref.x)
    np.testing.assert_array_equal(run.state.nfev, ref.nfev)
    assert run.state.status == ref.status


def _row_step(H, g, x, lo, hi, lam):
    """One material's damped step written out (the definition the batched solve must equal)."""
    free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
    d = np.zeros_like(x)
    if free.any():
        Hf = H[np.ix_(free, free)]
        diag = np.maximum(np.diag(Hf), 1e-12 * np.diag(Hf).max())
        d[free] = np.linalg.solve(Hf + lam * np.diag(diag), -g[free])
    dec = 0.0
    if free.any():
        dec = max(g[free] @ np.linalg.lstsq(H[np.ix_(free, free)], g[free], rcond=1e-12)[0], 0.0)
    return d, dec


def test_batched_steps_equal_each_materials_own():
    from brdfcl.optim.lm import lm_steps, newton_decrements
    rng = np.random.default_rng(3)
    m, k = 12, 6
    J = rng.normal(size=(m, 20, k)) * np.exp(rng.normal(size=(m, 1, k)))
    J[::3, :, 2] = J[::3, :, 3]                                  # singular free blocks (decrement only)
    H = np.einsum("mni,mnj->mij", J, J)
    g = rng.normal(size=(m, k))
    lo, hi = -np.ones(k), np.ones(k)
    x = rng.uniform(-0.5, 0.5, size=(m, k))
    x[1, :2] = 1.0
    g[1, :2] = -1.0                                              # held at the upper bound
    x[2] = -1.0
    g[2] = 1.0                                                   # every parameter held
    lam = 10.0 ** rng.uniform(-4, 2, size=m)
    d, dec = lm_steps(H, g, x, lo, hi, lam), newton_decrements(H, g, x, lo, hi)
    assert np.all(d[1, :2] == 0) and np.all(d[2] == 0) and dec[2] == 0
    for i in range(m):
        d_i, dec_i = _row_step(H[i], g[i], x[i], lo, hi, lam[i])
        np.testing.assert_allclose(d[i], d_i, rtol=1e-8, atol=1e-12 * np.abs(d_i).max(initial=1))
        assert dec[i] == pytest.approx(dec_i, rel=1e-6, abs=1e-12)
    assert lm_steps(H[:, :0, :0], g[:, :0], x[:, :0], lo[:0], hi[:0], lam).shape == (m, 0)   # nothing free


def test_a_row_at_its_floor_stops_converged_while_the_others_run():
    """A row whose loss is at or below its ``floor`` (an exact fit's rounding noise) stops before
    a launch as converged; the same row without a floor keeps stepping; the other rows are not
    affected.  Catches the exact demo fits that ran to the iteration limit on rounding noise."""
    lo, hi = np.full(2, -5.0), np.full(2, 5.0)
    res = [rosenbrock, rosenbrock]
    x0 = np.array([[1.001, 1.0], [-1.2, 1.0]])            # row 0 next to the minimum, row 1 far
    start = loss_at(rosenbrock, x0[0])
    b = Batch(res, lo, hi)
    st = levenberg_marquardt(b, x0, lo, hi, LMOptions(), floor=np.array([2 * start, 0.0]))
    assert st.status[0] == Status.NOISE_FLOOR and st.iters[0] == 0
    np.testing.assert_array_equal(st.x[0], x0[0])
    assert st.status[1].converged and st.loss[1] < 1e-10
    free = levenberg_marquardt(Batch(res, lo, hi), x0, lo, hi, LMOptions())
    assert free.iters[0] > 0 and free.status[0] != Status.NOISE_FLOOR
    np.testing.assert_array_equal(st.x[1], free.x[1])


def test_statuses_are_codes_with_messages():
    """As scipy.optimize: > 0 converged, 0 the iteration limit, < 0 no refined fit; each code's
    message, with a stage's note after it."""
    from brdfcl.optim.status import MESSAGES, message
    assert set(MESSAGES) == set(Status)
    assert [s for s in Status if s.converged] == [Status.FTOL, Status.PREDICTED_FTOL, Status.NOISE_FLOOR,
                                                  Status.NO_DECREASE, Status.SETTLED]
    assert not Status.ITERATION_LIMIT.converged and Status.ITERATION_LIMIT == 0
    assert message(Status.FTOL, "after reviving a lobe") == "converged (ftol); after reviving a lobe"
    assert Status.NOISE_FLOOR.text == "converged (at the noise floor)"


def test_a_row_above_its_ceiling_stops_after_behind_after_iterations():
    """Rosenbrock from far away takes more than BEHIND_AFTER iterations: with a ceiling below
    its loss then it stops there (Status.BEHIND), with an infinite one it converges; a row
    already below its ceiling is not stopped."""
    from brdfcl.optim.lm import BEHIND_AFTER
    x0 = np.array([[-1.9, 2.5], [-1.9, 2.5]])
    lo, hi = np.full(2, -5.0), np.full(2, 5.0)
    free = LMRun(Batch([rosenbrock, rosenbrock]), x0, lo, hi, LMOptions(max_iter=200))
    for _ in free.steps():
        pass
    assert free.state.iters[0] > BEHIND_AFTER and free.state.loss[0] < 1e-10
    run = LMRun(Batch([rosenbrock, rosenbrock]), x0, lo, hi, LMOptions(max_iter=200),
                ceiling=np.array([1e-12, np.inf]))
    for _ in run.steps():
        pass
    assert run.state.status[0] == Status.BEHIND and run.state.iters[0] == BEHIND_AFTER
    assert run.state.status[1].converged and run.state.loss[1] < 1e-10
