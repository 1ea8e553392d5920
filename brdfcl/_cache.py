"""brdfcl's own cache folder and the small JSON files it keeps there (vector widths, program
keys, kernel-cache fingerprints, platform checks, generated code), each replaced atomically."""
from __future__ import annotations

import hashlib
import json
import os
import zipfile
from contextlib import contextmanager
from pathlib import Path


def cache_dir() -> Path:
    """brdfcl's own cache: ``BRDFCL_CACHE_DIR``, else ``$XDG_CACHE_HOME/brdfcl`` or ``~/.cache/brdfcl``."""
    base = os.environ.get("BRDFCL_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = os.path.join(xdg, "brdfcl")
    return Path(base)


def read_json(path: Path) -> dict:
    """A JSON object of brdfcl's cache; {} when it is missing or not one."""
    try:
        d = json.loads(path.read_text())
        return d if isinstance(d, dict) else {}
    except (OSError, ValueError):
        return {}


def update_json(path: Path, key: str, value) -> None:
    """Set one key of a JSON object in brdfcl's cache, replacing the file atomically."""
    d = read_json(path)
    d[key] = value
    write_json(path, d)


def write_json(path: Path, d: dict) -> None:
    """Replace a JSON file of brdfcl's cache atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(json.dumps(d, indent=1, sort_keys=True))
    os.replace(tmp, path)


@contextmanager
def locked(path: Path):
    """Serialise a read-decide-write of one cache file between processes (Dask workers start
    together); a file system without locks gives no lock."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_suffix(".lock"), "w") as f:
        try:
            import fcntl
            fcntl.flock(f, fcntl.LOCK_EX)
        except (ImportError, OSError):
            pass
        yield


def generated(kind: str, key: str, make, keep: int | None = None) -> str:
    """Text that depends only on the code (a term's generated C or Python), made once per machine:
    read from ``generated/KIND/KEY.json`` in brdfcl's cache when it is there and whole, else
    ``make()`` and written atomically.  ``key`` must change whenever what ``make`` reads does (a
    hash of those sources); an unwritable cache makes the text in every process.  ``keep``: writing
    one removes all but the ``keep`` newest of its kind (for kinds with a file per configuration)."""
    path = cache_dir() / "generated" / kind / f"{key}.json"
    try:
        doc = json.loads(path.read_text())
        text = doc["text"]
        if isinstance(text, str) and doc.get("sha1") == hashlib.sha1(text.encode()).hexdigest():
            return text
    except (OSError, ValueError, KeyError, TypeError):
        pass
    text = make()
    try:
        write_json(path, {"text": text, "sha1": hashlib.sha1(text.encode()).hexdigest()})
        if keep is not None:
            _prune(path, "*.json", keep)
    except OSError:
        pass
    return text


def _prune(path: Path, pattern: str, keep: int) -> None:
    """Remove all but the ``keep`` newest files of ``pattern`` beside ``path`` (which stays)."""
    others = [p for p in path.parent.glob(pattern) if p != path]
    for old in sorted(others, key=lambda p: p.stat().st_mtime, reverse=True)[keep - 1:]:
        old.unlink(missing_ok=True)


KEEP_ARRAYS = 4                   # generated_arrays: the newest files kept of one kind


def generated_arrays(kind: str, key: str, make, keep: int = KEEP_ARRAYS) -> dict:
    """Arrays that depend only on the code, made once per machine: ``generated`` for a dict of
    numpy arrays, kept as ``generated/KIND/KEY.npz`` (no pickled objects).  They can be large:
    writing one removes all but the ``keep`` newest of its kind (those of older code)."""
    import numpy as np
    path = cache_dir() / "generated" / kind / f"{key}.npz"
    try:
        with np.load(path, allow_pickle=False) as f:
            return {k: f[k] for k in f.files}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        pass
    arrays = make()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp{os.getpid()}.npz")
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
        _prune(path, "*.npz", keep)
    except OSError:
        pass
    return arrays
