"""Worker processes that draw report images: ``python -m brdfcl.report.view.drawer``.

Drawing a material's images is Python and numpy under the GIL, so a report of many materials
draws them in one process per CPU.  The workers are plain child processes of the interpreter
(not multiprocessing's spawn, which would run the caller's main script again in each one): each
reads ``(function, arguments)`` pickles on its standard input and answers each with its result,
or the exception it raised, on its standard output; it ends at the end of its input.
"""
from __future__ import annotations

import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading
from concurrent.futures import Future

_HEAD = struct.Struct("<Q")


def _send(stream, obj) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEAD.pack(len(data)))
    stream.write(data)
    stream.flush()


def _receive(stream):
    head = stream.read(_HEAD.size)
    if len(head) < _HEAD.size:
        raise EOFError
    data = stream.read(_HEAD.unpack(head)[0])
    return pickle.loads(data)


class InProcess:
    """The pool's interface, each call run here at once."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def submit(self, fn, *args, worker=None) -> Future:
        f: Future = Future()
        f.set_result(fn(*args))
        return f


class Drawers:
    """``n`` worker processes; `submit` sends a call to worker ``worker`` or, by default, the one
    with the fewest pending, and returns a Future of its result (the worker's exception
    re-raised; a worker that died: a RuntimeError of one line).  ``nice``: the workers' niceness
    increment (os.nice); ``idle``: the workers also in Linux's SCHED_IDLE class, which runs them
    only on a core nothing else wants (a nice process still takes a share of a busy core, which
    stalls a parallel kernel's slowest thread), where they may leave it again (`wake`); both for
    workers beside other work."""

    def __init__(self, n: int, nice: int = 0, idle: bool = False):
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        args = [sys.executable, "-m", __name__, str(int(nice))] + (["idle"] if idle else [])
        self._procs = [subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
                       for _ in range(n)]
        self._pending: list[queue.Queue] = [queue.Queue() for _ in self._procs]
        self._outbox: list[queue.Queue] = [queue.Queue() for _ in self._procs]
        self._counts = [0] * n
        self._lock = threading.Lock()
        self._readers = [threading.Thread(target=self._read, args=(k,), daemon=True) for k in range(n)]
        # a call is sent by a thread of its worker: a full pipe (a busy worker) must not hold the
        # caller while another worker waits for its next call
        self._writers = [threading.Thread(target=self._write, args=(k,), daemon=True) for k in range(n)]
        for t in self._readers + self._writers:
            t.start()

    def _write(self, k):
        stdin, outbox = self._procs[k].stdin, self._outbox[k]
        while (call := outbox.get()) is not None:
            try:
                _send(stdin, call)
            except OSError:
                pass                      # the reader reports the dead worker on this call's future
        try:
            stdin.close()
        except OSError:
            pass

    def _read(self, k):
        proc, pending = self._procs[k], self._pending[k]
        while True:
            f = pending.get()
            if f is None:
                return
            try:
                status, value = _receive(proc.stdout)
            except (EOFError, OSError, pickle.UnpicklingError):
                f.set_exception(RuntimeError(f"report: an image worker ended (exit status {proc.wait()})"))
                continue
            with self._lock:
                self._counts[k] -= 1
            (f.set_result if status == "ok" else f.set_exception)(value)

    @property
    def size(self) -> int:
        return len(self._procs)

    def submit(self, fn, *args, worker=None) -> Future:
        with self._lock:
            k = min(range(len(self._procs)), key=self._counts.__getitem__) if worker is None else worker
            self._counts[k] += 1
        f: Future = Future()
        self._pending[k].put(f)
        self._outbox[k].put((fn, args))
        return f

    def wake(self) -> None:
        """Every worker back in the normal scheduling class (from SCHED_IDLE; its niceness kept):
        once nothing else runs beside them, other programs must not starve what is left."""
        for k in range(self.size):
            self.submit(_normal_class, worker=k)

    def __enter__(self):
        return self

    def __exit__(self, kind, value, tb):
        for proc, pending, outbox in zip(self._procs, self._pending, self._outbox):
            outbox.put(None)              # its input ends after what is queued
            pending.put(None)
            if kind is not None:          # interrupted or failed: what is queued is not wanted
                proc.kill()
        for proc, w, r in zip(self._procs, self._writers, self._readers):
            w.join()
            r.join()
            proc.wait()
        return False


def _may_leave_idle() -> bool:
    """Whether this process could return from SCHED_IDLE to the normal class: Linux allows it to
    root, or where RLIMIT_NICE admits the process's niceness (sched(7))."""
    import resource
    if os.geteuid() == 0:
        return True
    soft = resource.getrlimit(resource.RLIMIT_NICE)[0]
    return soft == resource.RLIM_INFINITY or 20 - os.nice(0) <= soft


def _normal_class() -> None:
    if hasattr(os, "SCHED_IDLE") and os.sched_getscheduler(0) == os.SCHED_IDLE:
        try:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        except OSError:
            pass


def main() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)     # Ctrl-C is the caller's to handle
    if len(sys.argv) > 1 and int(sys.argv[1]):
        os.nice(int(sys.argv[1]))
    if "idle" in sys.argv[2:] and hasattr(os, "SCHED_IDLE") and _may_leave_idle():
        try:
            os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
        except OSError:
            pass                          # not allowed here: the niceness alone
    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr               # a stray print must not break the answers
    while True:
        try:
            fn, args = _receive(stdin)
        except EOFError:
            return
        try:
            answer = ("ok", fn(*args))
        except Exception as e:            # sent back, raised in the caller
            answer = ("error", e)
        try:
            _send(stdout, answer)
        except (pickle.PicklingError, TypeError, AttributeError) as e:
            _send(stdout, ("error", RuntimeError(f"report: {answer[1]!r:.300} ({e})")))


if __name__ == "__main__":
    main()
