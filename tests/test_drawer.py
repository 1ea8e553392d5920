"""The report's image workers (brdfcl.report.view.drawer): plain child processes that answer
calls in order, raise their errors in the caller and end with their input."""
import os

import pytest

from brdfcl.report.view import drawer
from brdfcl.report.view.drawer import Drawers, InProcess


def test_results_come_back_in_order_from_every_worker():
    with Drawers(2) as pool:
        futures = [pool.submit(os.path.join, "a", str(i)) for i in range(9)]
        assert [f.result(timeout=60) for f in futures] == [os.path.join("a", str(i)) for i in range(9)]
    assert all(p.returncode == 0 for p in pool._procs)


def test_an_error_is_raised_in_the_caller_and_the_workers_go_on(tmp_path):
    with Drawers(2) as pool:
        bad = pool.submit(os.stat, str(tmp_path / "missing"))
        good = pool.submit(os.path.basename, "/x/y")
        with pytest.raises(FileNotFoundError):
            bad.result(timeout=60)
        assert good.result(timeout=60) == "y"


def test_leaving_on_an_error_stops_the_workers():
    with pytest.raises(KeyboardInterrupt):
        with Drawers(2) as pool:
            pool.submit(os.getpid)
            raise KeyboardInterrupt
    assert all(p.returncode is not None for p in pool._procs)


def test_in_process_runs_at_once():
    with InProcess() as pool:
        assert pool.submit(os.path.join, "a", "b").result() == os.path.join("a", "b")


def test_a_call_goes_to_the_worker_named_and_workers_run_at_their_niceness():
    with Drawers(2, nice=3) as pool:
        pids = [pool.submit(os.getpid, worker=k).result(timeout=60) for k in (0, 1, 0, 1)]
        assert pids[0] == pids[2] != pids[1] == pids[3]
        assert pool.size == 2
        assert pool.submit(os.nice, 0).result(timeout=60) == os.nice(0) + 3


@pytest.mark.skipif(not hasattr(os, "SCHED_IDLE"), reason="SCHED_IDLE is Linux's")
def test_idle_workers_run_only_in_idle_time_until_woken():
    with Drawers(1, nice=1, idle=True) as pool:
        may = pool.submit(drawer._may_leave_idle).result(timeout=60)
        expect = os.SCHED_IDLE if may else os.SCHED_OTHER
        assert pool.submit(os.sched_getscheduler, 0).result(timeout=60) == expect
        pool.wake()
        assert pool.submit(os.sched_getscheduler, 0).result(timeout=60) == os.SCHED_OTHER
        assert pool.submit(os.nice, 0).result(timeout=60) == os.nice(0) + 1


def test_a_busy_worker_holds_neither_the_caller_nor_the_other_workers():
    import time
    with Drawers(2) as pool:
        pool.submit(time.sleep, 2.0, worker=0)                   # busy for a while
        t = time.monotonic()
        big = pool.submit(len, b"x" * (8 << 20), worker=0)      # far more than a pipe holds
        quick = pool.submit(os.path.basename, "/a/b", worker=1)
        assert time.monotonic() - t < 1.0
        assert quick.result(timeout=60) == "b" and time.monotonic() - t < 1.5
        assert big.result(timeout=60) == 8 << 20
