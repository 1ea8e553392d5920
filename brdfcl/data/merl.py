"""MERL `.binary` reading and writing (docs/spec.md section 2).

File layout: three little-endian int32 ``90 90 180``, then ``3 * 1,458,000``
little-endian float64, all red, then all green, then all blue.  Cell index
``phi_d + 180 * (theta_d + 90 * theta_h)``.  Stored value times the channel
scale is the BRDF.  Negative, NaN and inf values mark missing cells.
"""
from __future__ import annotations

import mmap
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdfcl.data.geometry import N_CELLS, N_PD, N_TD, N_TH, TABLE
from brdfcl.data.measurement import Layout, Measurement, rgb_channels

__all__ = ["CHANNELS", "FILE_SIZE", "HEADER", "N_CELLS", "N_PD", "N_TD", "N_TH", "SCALE", "MerlError", "MerlFile",
           "MerlTable", "list_database", "material_name", "open_merl", "read_database", "read_merl", "read_merl_at",
           "read_merl_cells", "read_numbers", "write_merl"]
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
HEADER = np.array([N_TH, N_TD, N_PD], dtype="<i4")
FILE_SIZE = HEADER.nbytes + 3 * N_CELLS * 8
CHANNELS = ("r", "g", "b")
MAP_BELOW = N_CELLS // 4
"""Index sets of fewer cells than this are gathered from the file mapped into memory rather than
read whole: the report's 183,000 cells cost a third of a whole read (5-7 ms against 15-25 ms a
table, 2-core AMD EPYC, page cache), while the fit's 910,000 cost about as much either way.  A
file cut short in place during those few milliseconds ends the process (SIGBUS) where a read
would have raised; a file replaced by a new one (`write_merl`, most tools) cannot."""


class MerlError(ValueError):
    """A MERL file that cannot be used; the message names the file and the problem."""


@dataclass
class MerlTable(Measurement):
    """One measured material as stored: numbers (3, N_CELLS), NaN where missing.

    ``stored`` keeps the file's own numbers (before the channel scale) so that
    writing the table back gives the same bytes; ``brdf()`` applies the scale."""

    name: str
    path: str | None
    stored: np.ndarray        # (3, N_CELLS) float64, NaN = missing
    n_missing: int            # cells missing in at least one channel
    channels = rgb_channels()

    @property
    def layout(self) -> Layout:
        return TABLE

    def values_at(self, indices, outs) -> None:
        for o, idx in zip(outs, indices):
            self.brdf_at(idx, out=o)

    @property
    def valid(self) -> np.ndarray:
        return np.isfinite(self.stored).all(axis=0)

    def brdf(self, dtype=np.float64) -> np.ndarray:
        """BRDF values (3, N_CELLS) in 1/sr, NaN where missing."""
        out = self.stored.astype(dtype)
        out *= SCALE.astype(dtype)[:, None]
        return out

    def brdf_at(self, index, dtype=np.float64, out=None) -> np.ndarray:
        """BRDF values (3, len(index)) at some cells, without a copy of the whole table (into
        ``out`` when given)."""
        out = np.empty((3, len(index)), dtype=dtype) if out is None else out
        return scaled_at(self.stored, index, out)


class MerlFile(Measurement):
    """A MERL file, read only when its values are asked for (`values_at`: each thread reuses one
    read buffer, so a batch of tables costs no table-sized allocation per file)."""

    channels = rgb_channels()
    path: str

    def __init__(self, path):
        self.path = os.fspath(path)
        self.name = material_name(path)

    @property
    def layout(self) -> Layout:
        return TABLE

    def values_at(self, indices, outs) -> None:
        if not os.path.exists(self.path):
            raise MerlError(f"{self.path}: file disappeared before it could be read")
        read_merl_at(self.path, indices, outs, _buffer())

    def __repr__(self) -> str:
        return f"MerlFile({self.path!r})"


def open_merl(path) -> MerlFile:
    """A MERL file as a Measurement, its header and size checked now (MerlError, one line), its
    numbers read when a fit asks for them."""
    with _checked(path):
        pass
    return MerlFile(path)


open_merl.format_name = "MERL {} tables"  # type: ignore[attr-defined]


def material_name(path) -> str:
    return Path(path).name[: -len(".binary")] if str(path).endswith(".binary") else Path(path).stem


def scaled_at(stored: np.ndarray, index, out: np.ndarray) -> np.ndarray:
    """The BRDF (stored numbers times the channel scale) of ``stored`` (3, N_CELLS) at the cells
    ``index``, into ``out`` (3, len(index)) of any float type; returns ``out``."""
    for c in range(3):
        np.multiply(stored[c].take(index), SCALE[c], out=out[c], casting="same_kind")
    return out


def missing(values: np.ndarray) -> np.ndarray:
    """Where stored values mark a missing cell: negative, NaN or inf (one pass)."""
    with np.errstate(invalid="ignore"):
        return ~((values >= 0) & (values < np.inf))


def read_numbers(path, out: np.ndarray | None = None) -> np.ndarray:
    """A MERL file's numbers as stored, (3, N_CELLS) float64, after validating header and size;
    read into ``out`` ((3 * N_CELLS,) or (3, N_CELLS) float64) when given: a buffer reused
    between files spares a fresh 35 MB allocation per file, whose page faults cost as much as
    the read itself."""
    path = os.fspath(path)
    with _checked(path) as f:
        if out is None:
            raw = np.fromfile(f, dtype="<f8", count=3 * N_CELLS)
            got = raw.size * 8
        else:
            raw = out.reshape(-1)
            if raw.dtype != np.dtype("<f8") or raw.size != 3 * N_CELLS:
                raise ValueError(f"read buffer {out.dtype} {out.shape}: expected ({3 * N_CELLS},) float64")
            got = f.readinto(raw.data.cast("B"))
    if got != 3 * N_CELLS * 8:
        raise MerlError(f"{path}: file changed while reading ({got // 8} values read)")
    return raw.reshape(3, N_CELLS)


@contextmanager
def _checked(path) -> Iterator:
    """The open file, its header and size checked (MerlError, one line, naming the file: also for
    an OSError while it is open)."""
    path = os.fspath(path)
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as f:
            _check_header(path, f, size)
            yield f
    except OSError as e:
        raise MerlError(f"{path}: cannot read: {e.strerror or e}") from None


def _check_header(path: str, f, size: int) -> None:
    """MerlError unless the open file ``f`` of ``size`` bytes has MERL's header and size."""
    head = f.read(HEADER.nbytes)
    if len(head) < HEADER.nbytes:
        raise MerlError(f"{path}: not a MERL file: {size} bytes, shorter than the 12-byte header")
    dims = np.frombuffer(head, dtype="<i4")
    if not np.array_equal(dims, HEADER):
        raise MerlError(f"{path}: wrong header {tuple(int(d) for d in dims)}, "
                        f"expected dimensions (90, 90, 180)")
    if size != FILE_SIZE:
        raise MerlError(f"{path}: wrong size {size} bytes, expected {FILE_SIZE} "
                        f"(header + 3 x {N_CELLS} float64); file truncated or padded")


def read_merl(path) -> MerlTable:
    """Read a MERL file, validating header and size; missing cells become NaN.

    Holds exactly one float64 copy of the file's numbers."""
    raw = read_numbers(path)
    bad = missing(raw)
    np.copyto(raw, np.nan, where=bad)
    n_missing = int(np.count_nonzero(bad[0] | bad[1] | bad[2]))
    if n_missing == N_CELLS:
        raise MerlError(f"{os.fspath(path)}: every cell is missing (all values negative, NaN or inf)")
    return MerlTable(material_name(path), os.fspath(path), raw, n_missing)


_NUMBERS = threading.local()


def read_merl_cells(path, index) -> np.ndarray:
    """A MERL file's BRDF (3, len(index)) float64 (1/sr) at some cells, NaN where missing: the
    file's numbers read into a buffer each thread reuses (`read_merl_at`), so that reading many
    tables for a few cells each costs no table-sized allocation (7 ms a table against 48 ms
    for `read_merl` and a gather).  MerlError as `read_merl_at`."""
    out = np.empty((3, len(index)))
    read_merl_at(path, [index], [out], _buffer())
    return out


def _buffer() -> np.ndarray:
    """This thread's read buffer of one table's numbers."""
    buffer = getattr(_NUMBERS, "buffer", None)
    if buffer is None:
        buffer = _NUMBERS.buffer = np.empty(3 * N_CELLS)
    return buffer


def read_merl_at(path, indices, outs, buffer: np.ndarray | None = None) -> str:
    """Read a MERL file's BRDF (1/sr) at each index set straight into ``outs`` ((3, n_i) arrays,
    float32 or float64), NaN where missing: no table-sized copy beyond the file's numbers (read
    into ``buffer``, see `read_numbers`; for fewer than MAP_BELOW cells in all, taken from the
    file mapped into memory instead, with no copy at all).  Returns the material's name;
    MerlError (one line, naming the file) for a file that cannot be used, or whose cells of the
    first index set are all missing."""
    if sum(np.size(i) for i in indices) < MAP_BELOW:
        _gather_mapped(path, indices, outs)
    else:
        _gather(read_numbers(path, buffer), indices, outs)
    if len(indices) and np.size(indices[0]) and np.isnan(outs[0]).any(axis=0).all():
        raise MerlError(f"{os.fspath(path)}: every cell is missing within the fitted region "
                        f"(all values negative, NaN or inf)")
    return material_name(path)


def _gather(raw, indices, outs) -> None:
    """The BRDF of the stored numbers ``raw`` (3, N_CELLS) at each index set into ``outs``, NaN
    where missing."""
    for o, idx in zip(outs, indices):
        np.copyto(scaled_at(raw, idx, o), np.nan, where=missing(o))


def _gather_mapped(path, indices, outs) -> None:
    """`_gather` from the file mapped into memory, read-only (header and size checked first):
    only the pages holding the cells are touched, and nothing else is copied."""
    path = os.fspath(path)
    with _checked(path) as f:
        m = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    try:
        if len(m) != FILE_SIZE:
            raise MerlError(f"{path}: file changed while reading ({len(m)} bytes)")
        _gather(np.frombuffer(m, dtype="<f8", count=3 * N_CELLS, offset=HEADER.nbytes).reshape(3, N_CELLS),
                indices, outs)
    finally:
        try:
            m.close()
        except BufferError:       # a view still held by an exception's traceback: unmapped with it
            pass


def write_merl(path, table) -> None:
    """Write a MerlTable, or a BRDF array (3, N_CELLS) in 1/sr, as a MERL file.

    Missing (NaN) cells are written as -1.  Written atomically (temporary file,
    then rename), so a reader never sees half a file."""
    path = os.fspath(path)
    if isinstance(table, MerlTable):
        stored = table.stored.copy()
    else:
        brdf = np.asarray(table, dtype=np.float64)
        if brdf.shape != (3, N_CELLS):
            raise ValueError(f"{path}: table shape {brdf.shape}, expected (3, {N_CELLS})")
        stored = brdf / SCALE[:, None]
    stored[~np.isfinite(stored)] = -1.0
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(HEADER.tobytes())
        f.write(np.ascontiguousarray(stored, dtype="<f8").tobytes())
    os.replace(tmp, path)


def list_database(folder) -> list[str]:
    """Sorted `.binary` paths of a database folder; clear error if there are none."""
    folder = os.fspath(folder)
    if not os.path.isdir(folder):
        raise MerlError(f"{folder}: not a directory")
    paths = sorted(os.path.join(folder, f) for f in os.listdir(folder) if f.endswith(".binary"))
    if not paths:
        raise MerlError(f"{folder}: no .binary files in this directory")
    return paths


def read_database(folder):
    """Read every `.binary` in a folder: (tables, errors) where errors maps path to message."""
    tables, errors = [], {}
    for p in list_database(folder):
        try:
            tables.append(read_merl(p))
        except MerlError as e:
            errors[p] = str(e)
    return tables, errors
