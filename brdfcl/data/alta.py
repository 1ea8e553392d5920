"""Reader of ALTA's plain-text data files (``.alta``): tables on a Rusinkiewicz grid, or samples.

ALTA (the BRDF fitting library of Inria and CNRS) stores measurements as text: a header of
``#KEY value`` lines, then one row per measurement with the input coordinates, then the outputs,
then the confidence-interval columns of the first output::

    #DIM 3 3                      inputs, outputs
    #PARAM_IN RUSIN_TH_TD_PD      how the inputs give the directions
    #PARAM_OUT RGB_COLOR          what the outputs are (RGB_COLOR: 3, INV_STERADIAN: 1)
    #VS 2                         interval columns after the outputs (2: lower and upper, 1: +-)
    # a comment ("#" and a space)
    0.0002 0.0087 0.0087  0.021 0.019 0.017

Angles are radians.  ``RUSIN_TH_TD_PD`` rows are (theta_h, theta_d, phi_d) with phi_h = 0, the
construction of brdfcl.data.geometry.directions; ALTA exports a MERL table this way (every bin
centre, phi_d in (0, pi)).  Rows that form a regular grid (every combination of each axis'
values once, those below the horizon possibly left out) are a table: a `GridLayout` of that
grid, dense, with a lookup, so that the analysis and the report read it as they read a MERL
table.  Any other rows (those above the
horizon with every output measured), and every other parametrisation of
brdfcl.data.alta_params (``COS_TH``, ``COS_TH_TD``, ``RUSIN_TH_TD``, ``RUSIN_TH_PH_TD_PD``,
``ISOTROPIC_TV_TL_DPHI``, ``ISOTROPIC_TL_TV_PROJ_DPHI``, ``SPHERICAL_TL_PL_TV_PV``,
``CARTESIAN``; that module gives each convention), are scattered samples
(brdfcl.data.samples).  A ``COS_TH`` file (a 1-D slice) places every sample as ALTA does, at
theta_d = 0: wi = wo = h.

Outputs: ``RGB_COLOR`` (a BRDF in 1/sr per R, G, B, at the MERL channels' wavelengths) and
``INV_STERADIAN`` (one channel, at 0.55 um).  A file without ``#PARAM_OUT`` (ALTA's
UNKNOWN_OUTPUT) and one output is read as ``INV_STERADIAN``: ALTA's retro-reflection
measurements are written so.  Negative values mark missing cells, as in MERL files.  ALTA's
retro-reflection data come as ``.dat`` files: ``read_alta_dat`` reads a ``.dat`` whose header
has ALTA's ``#DIM`` and refuses any other.  A malformed file is one ``DataError`` line naming
the file, the line and the problem.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from brdfcl._words import count
from brdfcl.data.alta_params import PARAMS, directions
from brdfcl.data.errors import DataError, read_text
from brdfcl.data.geometry import DEFAULT_CUTOFF_DEG, coarse_cells, grid_directions, rusinkiewicz
from brdfcl.data.measurement import Channel, Layout, Measurement, rgb_channels
from brdfcl.data.samples import make_samples

OUTPUTS = {"RGB_COLOR": rgb_channels(), "INV_STERADIAN": (Channel("BRDF", 0.55),)}
"""The outputs read, with the channels they give."""
DEFAULT_OUTPUT = "INV_STERADIAN"
"""What a file without #PARAM_OUT holds when it has one output (ALTA's UNKNOWN_OUTPUT: ALTA's
retro-reflection measurements are BRDF values in 1/sr written so)."""

class GridLayout(Layout):
    """The cells of a regular (theta_h, theta_d, phi_d) grid, numbered theta_h slowest: each at its
    grid point, with the measure of the bin around it (edges half way between grid points;
    phi_d over [0, pi) folded by reciprocity, or over [0, 2 pi)).  One object per grid, shared by
    the tables on it."""

    dense = True

    def __init__(self, th: np.ndarray, td: np.ndarray, pd: np.ndarray):
        self.axes = (th, td, pd)
        self.shape = (th.size, td.size, pd.size)
        self.folded = pd.max() < np.pi * (1 + 1e-9)
        self.wi, self.wo = grid_directions(th, td, pd)
        w_th = 2 * np.pi * -np.diff(np.cos(_edges(th, 0.5 * np.pi)))
        w_td = 2 * np.diff(np.sin(_edges(td, 0.5 * np.pi)) ** 2)
        w_pd = np.diff(_edges(pd, np.pi if self.folded else 2 * np.pi)) * (2.0 if self.folded else 1.0)
        self.weight = (w_th[:, None, None] * w_td[None, :, None] * w_pd[None, None, :]).ravel()

    def _angles(self, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        i, j, _ = np.unravel_index(index, self.shape)
        return self.axes[0][i], self.axes[1][j]

    def select(self, cutoff_deg: float | None = DEFAULT_CUTOFF_DEG) -> np.ndarray:
        c = 0.0 if cutoff_deg is None or cutoff_deg >= 90 else np.cos(np.radians(cutoff_deg))
        return np.flatnonzero((self.wi[:, 2] > c) & (self.wo[:, 2] > c))

    def weights(self, index: np.ndarray, cutoff_deg: float | None = DEFAULT_CUTOFF_DEG) -> np.ndarray:
        return self.weight[index]

    def rows(self, index: np.ndarray) -> tuple[np.ndarray, ...]:
        th, td = self._angles(index)
        return np.sin(th), np.cos(th), np.cos(td), self.wi[index, 2], self.wo[index, 2]

    def coarse(self, index: np.ndarray, stride: int, peak_bins: int,
               peak_stride: int) -> tuple[np.ndarray, np.ndarray]:
        """As the MERL table's coarse subset (brdfcl.data.geometry.coarse_cells), by theta_h."""
        return coarse_cells(index, stride, peak_bins, peak_stride, theta_h=self._angles(index)[0])

    def lookup(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        th, td, pd = rusinkiewicz(np.asarray(wi, float), np.asarray(wo, float))
        ijk = [_nearest(axis, x) for axis, x in zip(self.axes, (th, td, pd))]
        cell = np.ravel_multi_index(ijk, self.shape)
        return np.where((wi[..., 2] > 0) & (wo[..., 2] > 0), cell, -1)


def _edges(axis: np.ndarray, top: float) -> np.ndarray:
    """Bin edges around sorted grid points: half way between them, 0 and ``top`` at the ends."""
    return np.concatenate([[0.0], 0.5 * (axis[1:] + axis[:-1]), [top]])


def _nearest(axis: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The index of the grid point nearest each x."""
    i = np.clip(np.searchsorted(axis, x), 1, axis.size - 1) if axis.size > 1 else np.zeros(np.shape(x), int)
    if axis.size > 1:
        i = np.where(np.abs(x - axis[i - 1]) <= np.abs(axis[i] - x), i - 1, i)
    return i


@lru_cache(maxsize=8)
def _grid(th: bytes, td: bytes, pd: bytes) -> GridLayout:
    """One GridLayout per grid, so that tables on one grid share it (and one upload)."""
    return GridLayout(*(np.frombuffer(a) for a in (th, td, pd)))


class AltaTable(Measurement):
    """An ALTA file whose rows fill a regular Rusinkiewicz grid: values (C, cells) in the grid's order."""

    def __init__(self, path: str, layout: GridLayout, values: np.ndarray, channels):
        self.path, self.name, self.channels = path, Path(path).stem, tuple(channels)
        self._layout, self.values = layout, values

    @property
    def layout(self) -> GridLayout:
        return self._layout

    def values_at(self, indices, outs) -> None:
        for o, idx in zip(outs, indices):
            o[...] = self.values[:, idx]


@dataclass(frozen=True)
class AltaRows:
    """An ALTA file's rows as written: the coordinates ``x`` (n, inputs) in ``param_in``, the
    values (n, outputs; NaN where negative, i.e. missing) in ``param_out`` and the line of each row."""

    path: str
    param_in: str
    param_out: str
    channels: tuple[Channel, ...]
    x: np.ndarray
    values: np.ndarray
    lines: np.ndarray

    def directions(self) -> tuple[np.ndarray, np.ndarray]:
        """The two directions (n, 3) of each row (brdfcl.data.alta_params)."""
        return directions(self.param_in, self.x)


def read_rows(path: str | os.PathLike[str]) -> AltaRows:
    """The rows of an ALTA text data file, checked against its header; DataError (one line:
    file, line, problem) if malformed or in a parametrisation brdfcl does not read."""
    path = os.fspath(path)
    header, first, rows = _split(path, read_text(path))
    if header.get("FORMAT", "text").lower() != "text":
        raise DataError(path, f"#FORMAT {header['FORMAT']}: brdfcl reads ALTA's text data files only")
    n_in, n_out = _dim(path, header)
    if not any(ln.strip() and not ln.lstrip().startswith("#") for ln in rows):
        raise DataError(path, "no data rows after the header (a file cut short?)")
    param_in, param_out = header.get("PARAM_IN", ""), header.get("PARAM_OUT", "")
    if param_in not in PARAMS:
        raise DataError(path, f"#PARAM_IN {param_in or '(none)'}: brdfcl reads {', '.join(PARAMS)}")
    if not param_out and n_out == 1:
        param_out = DEFAULT_OUTPUT
    if param_out not in OUTPUTS:
        raise DataError(path, f"#PARAM_OUT {param_out}: brdfcl reads {', '.join(OUTPUTS)}" if param_out else
                        f"no #PARAM_OUT and {count(n_out, 'output')}: without one brdfcl reads 1 output, "
                        f"a BRDF in 1/sr")
    channels = OUTPUTS[param_out]
    if (n_in, n_out) != (PARAMS[param_in], len(channels)):
        raise DataError(path, f"#DIM {n_in} {n_out}: {param_in} has {PARAMS[param_in]} inputs and {param_out} "
                              f"{count(len(channels), 'output')}")
    vs_field = header.get("VS", "").split()
    vs = {"2": 2, "1": 1}.get(vs_field[0] if vs_field else "", 0)
    data, lines = _numbers(path, first, rows, n_in + n_out + vs)
    values = data[:, n_in:n_in + n_out]
    values = np.where(values >= 0, values, np.nan)                   # negative: missing, as in MERL files
    return AltaRows(path, param_in, param_out, channels, data[:, :n_in], values, lines)


def read_alta(path: str | os.PathLike[str]) -> Measurement:
    """Read an ALTA text data file: an AltaTable where its RUSIN_TH_TD_PD rows fill a regular
    grid, else scattered Samples; DataError (one line: file, line, problem) if malformed."""
    rows = read_rows(path)
    path, x, values, channels = rows.path, rows.x, rows.values, rows.channels
    if rows.param_in == "RUSIN_TH_TD_PD":
        table = _as_table(path, x, values, channels)
        if table is not None:
            return table
    wi, wo = rows.directions()
    keep = (wi[:, 2] > 0) & (wo[:, 2] > 0) & np.isfinite(values).all(axis=1)    # measured, above the horizon
    if not keep.any():
        raise DataError(path, "no sample above the horizon with every value measured (non-negative)")
    wi, wo, values = wi[keep], wo[keep], values[keep]
    lines = [int(k) for k in rows.lines[keep]]
    ti, to = (np.arccos(np.clip(w[:, 2], -1, 1)) for w in (wi, wo))
    return make_samples(path, ti, np.arctan2(wi[:, 1], wi[:, 0]), to, np.arctan2(wo[:, 1], wo[:, 0]),
                        values, channels, lines=lines)


def is_alta_text(path: str | os.PathLike[str]) -> bool:
    """Whether a file's header (its first 64 KiB) has ALTA's ``#DIM`` line: a folder's ``.dat``
    files of other kinds are not measurements."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(65536)
    except OSError:
        return True                              # listed, so that reading it says why it cannot be
    return any(line.startswith(b"#DIM") for line in head.splitlines())


def read_alta_dat(path: str | os.PathLike[str]) -> Measurement:
    """A ``.dat`` file read as ALTA's (ALTA's retro-reflection data are ``.dat``), once its header
    shows it is one: a ``.dat`` of any other kind is a DataError saying so, not a misreading."""
    path = os.fspath(path)
    header, _, _ = _split(path, read_text(path))
    if "DIM" not in header:
        raise DataError(path, "not an ALTA data file (no #DIM header line): brdfcl reads a .dat file only in "
                              "ALTA's text format")
    return read_alta(path)


def _split(path: str, text: str) -> tuple[dict, int, list[str]]:
    """({key: value} of the header, the line number of the first row, the body's lines)."""
    lines = text.split("\n")
    header: dict[str, str] = {}
    k = 0
    while k < len(lines) and lines[k].startswith("#"):
        line = lines[k][1:]
        if line and not line[0].isspace() and not line.startswith("ALTA"):
            key, *value = line.split(None, 1)
            header[key] = value[0].strip() if value else ""
        k += 1
    return header, k + 1, lines[k:]


def _dim(path: str, header: dict) -> tuple[int, int]:
    fields = header.get("DIM", "").split()
    try:
        n_in, n_out = int(fields[0]), int(fields[1])
    except (IndexError, ValueError):
        raise DataError(path, "no #DIM line with the number of inputs and outputs (e.g. #DIM 3 3)") from None
    return n_in, n_out


def _numbers(path: str, first: int, lines: list[str], width: int) -> tuple[np.ndarray, np.ndarray]:
    """((rows, width) float64 of the body's lines, the line number of each) (blank and '#' lines
    skipped; columns beyond ``width`` ignored); DataError at the first line that is short or not
    numbers."""
    kept = [(first + k, ln.split()) for k, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
    if not kept:
        raise DataError(path, "no data rows after the header")
    short = next(((k, f) for k, f in kept if len(f) < width), None)
    if short is not None:
        raise DataError(path, f"{count(len(short[1]), 'number')}, expected at least {width} "
                              f"(#DIM inputs, outputs and #VS columns)", short[0])
    try:
        out = np.array([f[:width] for _, f in kept], dtype=np.float64)
    except ValueError:
        k, f = next((k, f) for k, f in kept if not _all_numbers(f[:width]))
        raise DataError(path, f"not a number: {next(x for x in f[:width] if not _is_number(x))!r}", k) from None
    bad = ~np.isfinite(out).all(axis=1)
    if bad.any():
        raise DataError(path, "a value is NaN or infinite: values must be finite numbers", kept[int(np.argmax(bad))][0])
    return out, np.array([k for k, _ in kept])


def _is_number(x: str) -> bool:
    try:
        float(x)
        return True
    except ValueError:
        return False


def _all_numbers(fields: list[str]) -> bool:
    return all(_is_number(x) for x in fields)


def _as_table(path: str, x: np.ndarray, values: np.ndarray, channels) -> AltaTable | None:
    """The rows as a table when they fill a regular grid (each axis' values sorted, every
    combination once); None otherwise."""
    axes, where = [], []
    for c in range(3):
        _, first, inv = np.unique(np.round(x[:, c], 9), return_index=True, return_inverse=True)
        axes.append(x[first, c])                    # the values as written, not their rounding
        where.append(inv.ravel())
    shape = tuple(a.size for a in axes)
    if np.prod(shape) < x.shape[0] or min(shape) < 2:
        return None
    cell = np.ravel_multi_index(where, shape)
    if np.unique(cell).size != cell.size:
        return None
    if cell.size < np.prod(shape):           # absent rows: only the grid's cells below the horizon
        wi, wo = grid_directions(*axes)
        absent = np.setdiff1d(np.arange(np.prod(shape)), cell)
        if ((wi[absent, 2] > 0) & (wo[absent, 2] > 0)).any():
            return None
    th, td, pd = axes
    if th[0] < 0 or th[-1] > 0.5 * np.pi + 1e-6 or td[0] < 0 or td[-1] > 0.5 * np.pi + 1e-6 or pd[0] < 0 \
            or pd[-1] > 2 * np.pi + 1e-6:
        raise DataError(path, "RUSIN_TH_TD_PD angles out of range: theta_h, theta_d in [0, pi/2], phi_d in "
                              "[0, 2 pi] (radians)")
    grid = np.full((len(channels), int(np.prod(shape))), np.nan)
    grid[:, cell] = values.T
    layout = _grid(*(np.ascontiguousarray(a, dtype=np.float64).tobytes() for a in axes))
    if np.isnan(grid[:, layout.select(None)]).all():
        raise DataError(path, "every cell above the horizon is missing (negative)")
    return AltaTable(path, layout, grid, channels)


read_alta.format_name = "ALTA {} files"  # type: ignore[attr-defined]
read_alta_dat.claims = is_alta_text  # type: ignore[attr-defined]
read_alta_dat.format_name = "ALTA {} files"  # type: ignore[attr-defined]
