"""A run's input files, and the rule that brdfcl never writes into them.

What every job (``brdfcl fit-all``, ``analyze``, a cluster task) does with its input before and
while fitting: list the database (``database_paths``), refuse an output folder that is, holds or is
inside the input data (``check_output_not_input``: InputOverwriteError, symlinks resolved) and one
that cannot be written (``check_output_dir``), before any work.
"""
from __future__ import annotations

import os
from pathlib import Path

from brdfcl.data.errors import DataError
from brdfcl.data.merl import MerlError
from brdfcl.data.readers import READERS, find_measurements, reader_for


class InputOverwriteError(ValueError):
    """An output that would be, hold or sit inside the input data (brdfcl never writes there)."""


def database_paths(source) -> list[str]:
    """A folder (the files of it a reader of brdfcl.data.readers reads, sorted by name), a single
    file, or a list of files."""
    if isinstance(source, (str, os.PathLike)):
        if os.path.isfile(source):
            if reader_for(source) is None:
                raise DataError(source, f"unknown format: brdfcl reads {', '.join(sorted(READERS))} files")
            return [os.fspath(source)]
        if not os.path.isdir(source):
            raise MerlError(f"{os.fspath(source)}: not a folder" if os.path.exists(source)
                            else f"{os.fspath(source)}: no such file or folder")
        found = [os.fspath(p) for p in find_measurements(source)]
        if not found:
            raise MerlError(f"{os.fspath(source)}: no measurement files in this folder ({', '.join(sorted(READERS))}; "
                            f"subfolders are not searched)")
        return found
    return [os.fspath(p) for p in source]


def _forms(path):
    """A path as given (absolute, normalised) and with every symlink resolved."""
    return {os.path.abspath(path), os.path.realpath(path)}


def _within(a, b):
    """a is b or inside it."""
    return a == b or os.path.commonpath([a, b]) == b


def check_output_not_input(source, out, paths=None):
    """Refuse (InputOverwriteError, one line) an output folder that is, is inside or holds the input
    folder, or that is or holds an input file; paths as given and with symlinks resolved (a
    folder of links: the links' targets are inputs too).  ``source``: folder, file or list of
    files as for fit_all; ``paths``: its files if already listed.  Call before any work
    (fit_all and brdfcl.analysis.analyze do)."""
    paths = database_paths(source) if paths is None else paths
    outs = _forms(out)
    if isinstance(source, (str, os.PathLike)) and os.path.isdir(source):
        for f in sorted(_forms(source)):
            for o in sorted(outs):
                how = ("is the input folder" if o == f else "is inside the input folder" if _within(o, f)
                       else "holds the input folder" if _within(f, o) else None)
                if how:
                    _refuse(out, how, f)
    for p in paths:
        files = _forms(p) | {os.path.join(os.path.realpath(os.path.dirname(os.path.abspath(p))),
                                          os.path.basename(p))}
        for f in sorted(files):
            for o in sorted(outs):
                if _within(f, o):
                    _refuse(out, "is the input file" if o == f else "holds the input file", f)


def _refuse(out, how, what):
    raise InputOverwriteError(f"output folder {out} {how} {what}: input data is read-only to brdfcl; "
                              f"choose an output folder outside the input data")


def check_output_dir(out):
    """Create ``out`` if needed and prove it writable: a one-line OSError naming it if not."""
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".write-test-{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError as e:
        raise OSError(f"{out}: output folder cannot be written: {e.strerror or e}") from None
    return out
