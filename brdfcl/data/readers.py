"""Measurement readers by file suffix: one registry that ``read_measurement`` and
``find_measurements`` (a folder mixing formats) both read.

To add a format, map its suffix (lower case, with the dot) to a callable taking the path and
returning a ``Measurement`` (brdfcl.data.measurement); a ``DataError`` with one line naming the
file is its way to refuse a malformed file.  The reader's ``format_name`` (``"Cornell {}
samples"``, the suffix in the braces) is how the command line names the format::

    READERS[".brdf"] = read_cornell

The longest registered suffix that ends a file's name wins (``.brdf.gz`` before ``.gz``).
"""
from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from .alta import read_alta, read_alta_dat
from .cornell import read_cornell
from .csvsamples import read_csv
from .errors import DataError
from .measurement import Measurement
from .merl import open_merl

Reader = Callable[[Path], Measurement]

READERS: dict[str, Reader] = {
    ".alta": read_alta,
    ".binary": open_merl,
    ".brdf": read_cornell,
    ".csv": read_csv,
    ".dat": read_alta_dat,          # refuses a .dat that is not ALTA's, in one line
}
"""Suffix -> reader.  The hook for more formats: add an entry.  A reader of a suffix other formats
share (``.dat``) has ``claims(path)``: a folder's files it does not claim are not listed."""


def formats_text(last: str = "and") -> str:
    """The formats READERS reads, for a user: ``MERL .binary tables, Cornell .brdf samples and .csv
    samples``."""
    names = [getattr(READERS[s], "format_name", "{} files").format(s) for s in sorted(READERS)]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} {last} {names[-1]}"


def reader_for(path: str | os.PathLike[str]) -> Reader | None:
    """The reader registered for this file's name, or None."""
    name = Path(path).name.lower()
    found = [s for s in READERS if name.endswith(s) and len(name) > len(s)]
    return READERS[max(found, key=len)] if found else None


def read_measurement(path: str | os.PathLike[str]) -> Measurement:
    """Read one measurement file with the reader its suffix names; DataError if none does (a
    reader's own error, e.g. MerlError, for a file it refuses)."""
    reader = reader_for(path)
    if reader is None:
        known = ", ".join(sorted(READERS))
        raise DataError(path, f"unknown format: no reader for this suffix (known: {known})")
    return reader(Path(path))


def find_measurements(folder: str | os.PathLike[str]) -> list[Path]:
    """The entries of a folder (not inside its subfolders) whose names a registered reader
    reads, sorted by name; hidden ones, and files of a shared suffix their reader does not claim
    (a ``.dat`` that is not ALTA's), are skipped.  A subfolder with such a name is listed, so that
    its reader says in one line why it cannot be read.  DataError if the folder cannot be
    listed."""
    root = Path(folder)
    if not root.is_dir():
        raise DataError(folder, "not a folder" if root.exists() else "no such folder")
    try:
        entries = sorted(root.iterdir(), key=lambda p: p.name)
    except OSError as e:
        raise DataError(folder, f"cannot list: {e.strerror or e}") from None
    found = []
    for p in entries:
        reader = None if p.name.startswith(".") else reader_for(p)
        if reader is not None and (p.is_dir() or getattr(reader, "claims", lambda _: True)(p)):
            found.append(p)
    return found


read_samples = read_measurement
"""The reader of a scattered-samples file (Cornell .brdf, CSV): a ``Samples``."""
