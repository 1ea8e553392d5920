"""A fitted model written as an ALTA data file (``brdfcl export NAME.json --alta OUT.alta``):
the model's values at a set of points, for ALTA's tools or for comparing with the measurement.

Where the points come from, first that applies:

1. ``at``: any ALTA data file; its own rows, written back in its parametrisation (the
   coordinates unchanged, row for row) with its outputs.
2. The measurement the fit was made from (NAME.json's ``"source"``), when it is still readable:
   an ALTA file as in 1; scattered samples (Cornell, CSV) as ``CARTESIAN`` pairs of their
   directions.
3. Otherwise (a MERL table, or no readable source): `DEFAULT_GRID`, ``RUSIN_TH_TD_PD`` at every
   third MERL bin centre of each axis, less the cells below the horizon (ALTA has no mark of a
   missing value: its loaders read -1 as data), a grid that brdfcl reads back as a table.

The values are the model's float64 reference (``Model.reference``, the formulas every fit is
checked against) at each point's two directions (brdfcl.data.alta_params); a file's pair below
the horizon has none and is written -1, so that the rows stay those of the file.  Outputs: a
file's own (``RGB_COLOR`` or ``INV_STERADIAN``); else ``RGB_COLOR`` for a fit of three channels,
``INV_STERADIAN`` for one.  One output from several channels is their mean (as ALTA converts
colours to one value); three from one channel repeat it.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdfcl.data.alta import OUTPUTS, read_alta, read_alta_dat, read_rows
from brdfcl.data.alta_params import directions
from brdfcl.data.alta_write import alta_text
from brdfcl.data.errors import DataError
from brdfcl.data.geometry import bin_centres
from brdfcl.data.readers import read_measurement, reader_for
from brdfcl.data.samples import Samples
from brdfcl.model.lobes.cells import Cells
from brdfcl.report.export.fitfile import load_fit
from brdfcl.report.files import atomic_write_text, writing

GRID_STRIDE = 3
"""`DEFAULT_GRID` takes every GRID_STRIDE-th MERL bin centre of each axis: 30 x 30 x 60 points."""
DEFAULT_GRID = "RUSIN_TH_TD_PD"


@dataclass(frozen=True)
class Points:
    """Where a fit is written: rows ``x`` in ``param_in``, the outputs (None: the fit's own) and
    what they are, for the file's comment and the user."""

    param_in: str
    x: np.ndarray
    param_out: str | None
    origin: str
    path: str | None = None          # the file the points are read from


def default_grid() -> Points:
    th, td, pd = (a[::GRID_STRIDE] for a in bin_centres())
    grid = np.stack(np.meshgrid(th, td, pd, indexing="ij"), axis=-1).reshape(-1, 3)
    return Points(DEFAULT_GRID, grid, None, f"a {DEFAULT_GRID} grid of {th.size} x {td.size} x {pd.size} "
                                            f"MERL bin centres")


def _file_points(path: str, what: str = "") -> Points:
    rows = read_rows(path)
    return Points(rows.param_in, rows.x, rows.param_out, f"the {len(rows.x)} points of {what}{path}", path)


def points_for(doc: dict, at: str | os.PathLike[str] | None = None) -> Points:
    """The points a fit document is written at (the module's docstring gives the rule);
    DataError (one line) if ``at`` is not a readable ALTA file."""
    if at is not None:
        return _file_points(os.fspath(at))
    source = doc.get("source")
    if isinstance(source, str) and os.path.isfile(source):
        try:
            if reader_for(source) in (read_alta, read_alta_dat):
                return _file_points(source, "the measurement ")
            m = read_measurement(source)
        except (DataError, OSError):
            return default_grid()
        if isinstance(m, Samples):
            return Points("CARTESIAN", np.hstack([m.wi, m.wo]), None,
                          f"the {m.n_samples} sample directions of the measurement {source}", source)
    return default_grid()


def _outputs(name: str, values: np.ndarray, param_out: str | None) -> tuple[str, np.ndarray]:
    """(ALTA output, values (n, outputs)) of model values (C, n) for the output asked for."""
    c = values.shape[0]
    if param_out is None:
        if c not in (1, 3):
            raise ValueError(f"{name}: a fit of {c} spectral channels; ALTA's outputs are RGB_COLOR (3) and "
                             f"INV_STERADIAN (1): fit with --rgb, or give --at an ALTA file to write one value")
        param_out = "RGB_COLOR" if c == 3 else "INV_STERADIAN"
    p = len(OUTPUTS[param_out])
    if p == c:
        return param_out, values.T
    if p == 1:
        return param_out, values.mean(axis=0)[:, None]
    if c == 1:
        return param_out, np.repeat(values.T, p, axis=1)
    raise ValueError(f"{name}: a fit of {c} channels cannot be written as {param_out} ({p} values)")


def fitted_values(model, values: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """The model's float64 reference (C, n) at direction pairs; NaN where a pair has no value
    (either direction at or below the horizon, or the two opposite)."""
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0) & (np.linalg.norm(wi + wo, axis=-1) > 1e-12)
    out = np.full((model.n_channels, len(wi)), np.nan)
    if ok.any():
        out[:, ok] = model.reference(Cells.from_directions(wi[ok], wo[ok]), values, jacobian=False)
    return out


def write_alta_fit(path: str | os.PathLike[str], doc: dict,
                   at: str | os.PathLike[str] | None = None) -> tuple[Path, Points]:
    """Write the fit of ``doc`` (a NAME.json document) as an ALTA data file at ``path``
    (atomically); returns the path and the points it was written at."""
    path = Path(path)
    fit = load_fit(doc)
    points = points_for(doc, at)
    if points.path is not None and path.exists() and os.path.samefile(path, points.path):
        raise ValueError(f"{path}: would overwrite the file whose points it is written at")
    wi, wo = directions(points.param_in, points.x)
    f = fitted_values(fit.model, fit.values, wi, wo)
    x = points.x
    if points.path is None:
        # ALTA has no mark of a missing value (its loaders read -1 as data): a grid of brdfcl's
        # own leaves out the pairs below the horizon; a file's points are kept row for row
        keep = np.isfinite(f).all(axis=0)
        x, f = x[keep], f[:, keep]
    param_out, values = _outputs(fit.name, f, points.param_out)
    comments = (f"brdfcl fit of {fit.name}: {fit.model.spec}", f"at {points.origin}",
                "values: the fitted model in 1/sr" + ("; -1: no value (below the horizon), row for row with "
                                                      "that file" if points.path is not None else ""))
    text = alta_text(points.param_in, x, values, param_out, comments)
    with writing(path):
        atomic_write_text(path, text)
    return path, points
