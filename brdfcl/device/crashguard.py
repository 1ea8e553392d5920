"""A guard around building and self-testing a program: a run that died there moves the program
to a new PoCL cache key for good.

PoCL aborts the whole process on some broken cache entries, which no check in Python can catch.
A marker file says a process is building and testing a program; the next run that finds the
marker of a dead process builds under the next cache key (``attempt``), and so does every run
after it, so one crash does not break every later run.  The attempt per program is kept in
``program-keys.json`` in brdfcl's cache.
"""
from __future__ import annotations

import hashlib
import os
from contextlib import contextmanager

from brdfcl._cache import cache_dir, read_json, update_json


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def _guard_key(source: str, device) -> str:
    return hashlib.sha1(f"{device.name}\0{device.driver_version}\0{source}".encode()).hexdigest()[:20]


@contextmanager
def crash_guard(source: str, device, log=None):
    """Yields the cache-key attempt to build ``source`` with.  A marker file says this process is
    building and testing the program; a marker left by a process that died there (PoCL aborts
    the whole process on some broken cache entries, which no check in Python can catch) moves
    this program to the next cache key for good, so one crash does not break every later run."""
    key = _guard_key(source, device)
    d = cache_dir() / "building"
    salts = cache_dir() / "program-keys.json"
    try:
        d.mkdir(parents=True, exist_ok=True)
        attempt = int(read_json(salts).get(key, 0))
        dead = [m for m in d.glob(f"{key}.*") if m.suffix[1:].isdigit() and not _alive(int(m.suffix[1:]))]
        if dead:
            attempt += 1
            update_json(salts, key, attempt)
            for m in dead:
                m.unlink(missing_ok=True)
            if log:
                log(f"brdfcl: a run died building or testing this program on {device.name}; "
                    f"building it under a new PoCL cache key")
        marker = d / f"{key}.{os.getpid()}"
        marker.write_text("")
    except OSError:                     # no writable cache: build without the guard
        yield 0
        return
    try:
        yield attempt
    finally:
        marker.unlink(missing_ok=True)


def keep_attempt(source: str, device, attempt: int) -> None:
    """A build under cache-key ``attempt`` worked where the one before failed: later runs start
    there (else each would meet the broken entry again, and the pip PoCL aborts at exit after a
    failed build)."""
    try:
        update_json(cache_dir() / "program-keys.json", _guard_key(source, device), attempt)
    except OSError:
        pass
