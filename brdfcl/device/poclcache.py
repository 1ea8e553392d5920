"""Repair of PoCL's kernel cache before a process's first build, and fingerprints of what a
sound program left there.

PoCL keeps compiled programs in a cache (``POCL_CACHE_DIR``, default ``~/.cache/pocl``).  An
entry left broken by a crash makes every later run fail, and some make PoCL abort the whole
process, which no check in Python can catch.  So, once per process and cache, entries with an
incomplete file (brdfcl.device.soundness) or with a file that differs from the print brdfcl took
when that entry last worked (brdfcl.device.fingerprints) are removed; PoCL compiles them again on
demand.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path

from brdfcl.device.fingerprints import digest, digest_of, matches, merge_prints, read_prints, stat_print
from brdfcl.device.soundness import sound

_REPAIRED: set = set()


def pocl_cache_dir(platform) -> Path | None:
    """PoCL's kernel cache for a PoCL platform (None for other platforms)."""
    if "portable computing" not in platform.name.lower():
        return None
    base = os.environ.get("POCL_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = os.path.join(xdg, "pocl")
    return Path(base) / "kcache" if (Path(base) / "kcache").is_dir() else Path(base)


def _dirs(path: str) -> list:
    try:
        with os.scandir(path) as it:
            return [e for e in it if e.is_dir(follow_symlinks=False)]
    except OSError:
        return []


def cache_files(root: Path) -> list:
    """(file, its entry folder) as strings for the program bitcode (``*/*/*.bc``) and the kernel
    libraries (``*/*/*/*/*.so``, the entry three levels up) of a PoCL cache (a walk of plain
    strings: pathlib's glob is slow on a cache of thousands of entries)."""
    out: list = []
    for a in _dirs(os.path.abspath(root)):
        for entry in _dirs(a.path):
            try:
                with os.scandir(entry.path) as it:
                    items = list(it)
            except OSError:
                continue
            for c in items:
                if c.name.endswith(".bc") and c.is_file(follow_symlinks=False):
                    out.append((c.path, entry.path))
                elif c.is_dir(follow_symlinks=False):
                    for d in _dirs(c.path):
                        try:
                            with os.scandir(d.path) as it:
                                out += [(f.path, entry.path) for f in it if f.name.endswith(".so")]
                        except OSError:
                            continue
    return out


def remember_pocl_cache(platform, since_ns: int) -> None:
    """Fingerprint the cache files PoCL wrote since ``since_ns`` (call it once their program has
    passed its self-test): a later run removes an entry whose file no longer matches."""
    root = pocl_cache_dir(platform)
    if root is None or not root.is_dir():
        return
    new = {}
    for path, _ in cache_files(root):
        try:
            st = os.stat(path)
            if st.st_mtime_ns >= since_ns:
                new[path] = stat_print(st, digest(path))
        except OSError:
            continue
    if new:
        try:
            merge_prints(new)
        except OSError:
            pass


def repair_pocl_cache(platform, log=None) -> list:
    """Remove cache entries with an incomplete file, or with a file that no longer matches its
    fingerprint (PoCL rebuilds them); once per process and cache.  A file found sound is
    remembered by its size and times, so a run reads only the files new or changed since the last
    (reading every file of a cache of thousands of entries would slow every start).  Returns the
    removed entry folders."""
    root = pocl_cache_dir(platform)
    if root is None or root in _REPAIRED or not root.is_dir():
        return []
    _REPAIRED.add(root)
    prints = read_prints()
    removed, checked = [], {}
    for path, entry in cache_files(root):
        if entry in removed:
            continue
        known = prints.get(path)
        if known is not None and matches(path, known):
            try:                # unchanged since it passed a self-test or this check: not read again
                fresh = stat_print(os.stat(path), digest_of(known))
                if fresh != known:          # same content, new times (or an older print): refresh
                    checked[path] = fresh
            except OSError:
                pass
            continue
        if digest_of(known) is None and sound(Path(path)):
            try:
                checked[path] = stat_print(os.stat(path), None)
            except OSError:
                pass
            continue
        shutil.rmtree(entry, ignore_errors=True)
        removed.append(entry)
    if checked or removed:      # remember what was checked, so that the next run reads only new files
        try:
            merge_prints(checked)
        except OSError:
            pass
    if removed and log:
        log(f"brdfcl: removed a broken PoCL kernel-cache entr{'y' if len(removed) == 1 else f'ies ({len(removed)})'}"
            f" from {root}; PoCL compiles them again")
    return removed
