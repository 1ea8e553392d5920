"""A run's input files, and the rule that brdfcl never writes into them.

What every job (``brdfcl fit-all``, ``analyze``, a cluster task) does with its input before and
while fitting: list the database (``database_paths``), read one file at a time under its path
(``FileReader``), refuse an output folder that is, holds or is inside the input data
(``check_output_not_input``: InputOverwriteError, symlinks resolved) and one that cannot be written
(``check_output_dir``), before any work.  It depends on brdfcl.data.merl alone, so the job runner
(brdfcl.app.run), the analysis and the cluster runner all import it from below.
"""
from __future__ import annotations

import os
from pathlib import Path

from brdfcl.data.merl import MerlError, list_database, read_merl, read_merl_at
from brdfcl.data.readers import READERS, find_measurements


class InputOverwriteError(ValueError):
    """An output that would be, hold or sit inside the input data (brdfcl never writes there)."""


def database_paths(source) -> list[str]:
    """A folder (its MERL .binary files and the scattered-sample files brdfcl.data.readers reads:
    .brdf, .csv; sorted by name), a single file, or a list of files."""
    if isinstance(source, (str, os.PathLike)):
        if os.path.isfile(source):
            return [os.fspath(source)]
        samples = [os.fspath(p) for p in find_measurements(source)] if os.path.isdir(source) else []
        if not samples:
            if os.path.isdir(source) and not any(is_table(f) for f in os.listdir(source)):
                raise MerlError(f"{os.fspath(source)}: no measurement files in this folder (MERL .binary, "
                                f"{', '.join(sorted(READERS))})")
            return list_database(source)          # its one-line error when it is not a folder
        tables = [p for p in (os.path.join(source, f) for f in os.listdir(source)) if is_table(p)]
        return sorted(tables + samples, key=lambda p: os.path.basename(p))
    return [os.fspath(p) for p in source]


def is_table(path) -> bool:
    """A MERL table (.binary); anything else a reader of brdfcl.data.readers reads as samples."""
    return os.fspath(path).lower().endswith(".binary")


class FileReader:
    """Reads one file when called; named by its path so that errors can say which."""

    def __init__(self, path):
        self.path = path

    def __call__(self):
        self._present()
        return read_merl(self.path)

    def values_at(self, indices, outs, buffer=None) -> str:
        """The file's BRDF at each index set into ``outs``, its name returned (brdfcl.data.merl.read_merl_at)."""
        self._present()
        return read_merl_at(self.path, indices, outs, buffer)

    def _present(self) -> None:
        if not os.path.exists(self.path):
            raise MerlError(f"{self.path}: file disappeared before it could be read")

    def __str__(self):
        return self.path


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
