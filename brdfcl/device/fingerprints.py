"""The fingerprints brdfcl keeps of PoCL's kernel-cache files (``pocl-fingerprints.json`` in
brdfcl's cache).

A cache file damaged in place keeps its length, so no structural check sees it (LLVM then aborts:
"Invalid abbrev number"); its content does.  A file's print is its size, modification and change
times and, where its program passed a self-test, its SHA-1.  A file unchanged in size and times
since it was printed is not read again, so checking a cache of thousands of entries stays cheap.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

from brdfcl._cache import cache_dir, read_json, write_json


def fingerprints_file() -> Path:
    """Where the prints are kept: {file path: print}."""
    return cache_dir() / "pocl-fingerprints.json"


def read_prints() -> dict:
    """The prints kept ({} when there are none)."""
    return read_json(fingerprints_file())


def digest(path: str) -> str:
    """A file's SHA-1."""
    return hashlib.sha1(Path(path).read_bytes()).hexdigest()


def stat_print(st: os.stat_result, digest: str | None) -> list:
    """A file's print: size, modification and change times (ctime cannot be set back by a
    restore or ``touch``), and its SHA-1 where it passed a self-test (None: only found sound)."""
    return [st.st_size, st.st_mtime_ns, digest, st.st_ctime_ns]


def digest_of(print_) -> str | None:
    """The digest of a print, None for a stat-only print or a malformed one."""
    return print_[2] if isinstance(print_, list) and len(print_) >= 3 and isinstance(print_[2], str) else None


def matches(path: str, print_) -> bool:
    """True when a file is the one printed: same size and times, or else (a self-tested file
    only) the same content."""
    try:
        st = os.stat(path)
        size, mtime = print_[0], print_[1]
        ctime = print_[3] if len(print_) > 3 else None
        if st.st_size == size and st.st_mtime_ns == mtime and st.st_ctime_ns == ctime:
            return True
        d = digest_of(print_)
        return st.st_size == size and d is not None and digest(path) == d
    except (OSError, ValueError, TypeError, IndexError, KeyError):
        return False


def merge_prints(new: dict) -> None:
    """Add prints to the file, read again just before writing (another process may have written
    since): a self-test's print (with a digest) is never replaced by a stat-only one; prints of
    files gone are dropped."""
    prints = read_json(fingerprints_file())
    for k, v in new.items():
        if digest_of(v) is None and digest_of(prints.get(k)) is not None and matches(k, prints[k]):
            continue
        prints[k] = v
    write_json(fingerprints_file(), {k: v for k, v in prints.items() if os.path.exists(k)})
