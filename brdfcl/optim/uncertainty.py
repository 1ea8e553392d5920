"""What a fit is worth: standard errors and correlations of its parameters, the directional albedo
of the fitted model, and flags for values a user should not trust.

Standard errors
---------------
The fit minimises ``L = sum_cells w sum_ch r^2`` with ``w`` the cells' solid-angle weights.  These
are quadrature weights, not inverse variances, and the noise of measured BRDFs is far from
constant in the fit metric (multiplicative noise under the log metric gives residuals of about
``eps x / (1 + x)``: the specular peak's cells scatter orders of magnitude more than the diffuse
cells).  So neither ``sigma^2 H^-1`` (weights as inverse variances) nor the homoscedastic
``sigma^2 H^-1 (J^T W^2 J) H^-1`` is right.  Linearising the normal equations at the optimum,
``theta - theta_0 = -H^-1 sum_c w_c g_c`` with ``g_c = sum_ch r J`` per cell, gives the sandwich

    cov = H^-1 M H^-1,   H = J^T W J,   M = sum_cells w^2 g_c g_c^T      (HC0, "robust")

which holds whatever the noise level of each cell, with cells (their three channels together)
as the independent units: exactly what a bootstrap over cells measures.  On synthetic
diffuse+GGX materials with multiplicative noise the sandwich's standard errors match the spread of
bootstrap refits per parameter, where the homoscedastic form underestimates the specular
parameters' by an order of magnitude and ``sigma^2 H^-1`` is off by up to a factor of two either
way (tests/test_uncertainty.py checks the sandwich against the bootstrap and gives the figures).

``H`` and ``M`` come from the kernels (``Engine.jtj`` and ``Engine.meat``, over every fitted
cell, one launch each for all materials finishing together), plus the Gauss-Newton Hessian of the
peak-order penalty in ``H`` when the fit has one (it is a constraint, not data, so it enters H
and not M).  ``meat`` here is the float64 reference of ``M`` the kernel is checked against; it
also sums ``M`` for a model too large for the kernel (brdfcl.kernels.codegen.MEAT_MAX_FREE), on a
systematic subsample of the fitted cells (every ``stride``-th in table order, at most
``MEAT_CELLS`` cells, scaled by the stride: on the full table every 46th, whose standard errors
are within 6% of those of every cell for GGX lobes of alpha 0.1 to 1e-3).  Parameters at a bound
are held (their rows and columns are left out: standard errors conditional on them) and get no
standard error (None, JSON null), as do fixed parameters.  All values are in natural units (not
the optimiser's log space); for a log-flagged parameter ``std_error / value`` is the standard
error of its logarithm.  A residual that is systematic (a model that does not fit) is treated as
noise of independent cells; the errors then say how much the fit depends on which cells were
measured, not how far the model is from the truth.

What is attached to each fit (these errors, the directional albedo of brdfcl.optim.albedo and the
flags) is assembled in brdfcl.optim.assessment.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from brdfcl.data.geometry import TABLE
from brdfcl.device.engine import CellSet, Engine
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.metrics import transform

MEAT_CELLS = 20_000                     # cells of the reference's middle term (see module doc)


# --- standard errors -----------------------------------------------------------------------------
@dataclass
class Uncertainty:
    """Standard errors of one fit: ``std_error`` by parameter name (None: fixed, at a bound or not
    determined), the correlation of those that have one, and the method in one line."""

    std_error: dict
    names: list
    correlation: np.ndarray
    method: str

    def as_json(self) -> dict:
        """The NAME.json form: {"std_error", "correlation": {"names", "matrix"}, "method"}."""
        mat = [[json_number(c, 6) for c in row] for row in np.asarray(self.correlation)]
        return {"std_error": {k: json_number(v) for k, v in self.std_error.items()},
                "correlation": {"names": list(self.names), "matrix": mat}, "method": self.method}


def json_number(v: float | None, digits: int | None = None) -> float | None:
    """A float for JSON: None where not finite, rounded to ``digits`` when given."""
    if v is None or not np.isfinite(v):
        return None
    return float(round(float(v), digits)) if digits else float(v)


def meat_stride(n_cells: int) -> int:
    return max(1, math.ceil(n_cells / MEAT_CELLS))


def method_line(stride: int | None, penalty: bool = False) -> str:
    """NAME.json's line on how the errors were computed (``stride`` None: M by the kernels, over
    every cell)."""
    if stride is None:
        every = "every fitted cell"
    else:
        nth = f"{stride}{'th' if 10 <= stride % 100 < 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(stride % 10, 'th')}"
        every = ("every cell" if stride == 1 else f"every {nth} cell") + " (float64 reference)"
    return (f"sandwich H^-1 M H^-1 (HC0, cells independent): H = J^T W J on the fitted cells"
            f"{' plus the peak-order penalty' if penalty else ''}, M = sum w^2 (J^T r)(J^T r)^T over "
            f"{every}; natural units; parameters at a bound held fixed")


def meat(model: Model, index: np.ndarray, data: np.ndarray, values: np.ndarray, metric: str = "log",
         cosw: bool = True, stride: int = 1, rows: np.ndarray | None = None, cs: CellSet | None = None) -> np.ndarray:
    """The float64 reference of ``Engine.meat``: ``M = sum_cells w^2 g g^T``, ``g = sum_ch r
    dr/dtheta`` (n, k, k) for each material, on every ``stride``-th of the cells ``index`` (table
    order) scaled by the stride.  ``data``: measured
    values at ``index`` (NaN: missing), (materials, channels, index.size); fit i is of material
    ``rows[i]`` (default i); ``values``: (n, n_params) natural.  A cell set ``cs`` of scattered
    samples gives each material's own cells and weights instead of the table's."""
    k = model.n_free
    out = np.zeros((len(values), k, k))
    for i, v in enumerate(np.atleast_2d(values)):
        row = i if rows is None else rows[i]
        if cs is not None and not cs.shared:
            every = cs.cells(row)
            sub = np.arange(stride // 2, len(every), stride)
            cells = Cells(*(getattr(every, a)[sub] for a in ("sh", "ch", "cd", "ci", "co")))
            w, cos_i = cs.weights(row)[sub], cells.ci
        else:
            sub, cells, w, cos_i = _subsample(index, stride, cs)
        cw = cos_i if cosw else np.ones(sub.size)
        w2 = w * w
        m = np.asarray(data[row][:, sub], dtype=np.float64)
        ok = np.isfinite(m)
        p, J = model.reference(cells, v)
        gp, dg = transform(metric, p * cw)
        r = np.where(ok, gp - transform(metric, np.where(ok, m, 0.0) * cw)[0], 0.0)
        gc = np.zeros((sub.size, k))
        for c in range(J.shape[0]):
            gc += J[c] * (r[c] * dg[c] * cw)[:, None]
        gc = np.where(np.isfinite(gc), gc, 0.0)
        out[i] = stride * ((gc * w2[:, None]).T @ gc)
    return out


_SUBSAMPLES: dict = {}


def _subsample(index, stride, cs: CellSet | None = None):
    """(positions in index, Cells, weights, cos theta_i) of every stride-th cell of a shared layout
    (``cs``'s; without one, the MERL table's), kept per index set."""
    key = (id(index), index.size, stride)            # the entry keeps index alive: ids stay unique
    if key not in _SUBSAMPLES or _SUBSAMPLES[key][0] is not index:
        layout = cs.place().layout if cs is not None else TABLE
        sub = np.arange(stride // 2, index.size, stride)
        idx = index[sub]
        if len(_SUBSAMPLES) > 8:
            _SUBSAMPLES.clear()
        cells = Cells(*layout.rows(idx))
        _SUBSAMPLES[key] = (index, sub, cells, layout.weights(idx, None if cs is None else cs.cutoff_deg), cells.ci)
    return _SUBSAMPLES[key][1:]


def sandwich(H: np.ndarray, M: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Covariance (k, k) of the kept columns (others NaN), from H (bread) and M (meat).

    H is inverted on its unit-diagonal scaling with eigenvalues floored at 1e-14 of the largest:
    a direction the data do not determine gets a huge, not a missing, variance."""
    k = H.shape[0]
    cov = np.full((k, k), np.nan)
    keep = np.flatnonzero(keep & (np.diag(H) > 0) & np.isfinite(np.diag(H)))
    if keep.size == 0:
        return cov
    Hk, Mk = H[np.ix_(keep, keep)], M[np.ix_(keep, keep)]
    d = 1.0 / np.sqrt(np.diag(Hk))
    lam, V = np.linalg.eigh(Hk * d[:, None] * d[None, :])
    lam = np.maximum(lam, 1e-14 * max(lam.max(), 1e-300))
    Hinv = (V / lam) @ V.T * d[:, None] * d[None, :]
    cov[np.ix_(keep, keep)] = Hinv @ Mk @ Hinv
    return cov


def from_covariance(model: Model, cov: np.ndarray, method: str) -> Uncertainty:
    free = [model.names[i] for i in model.free_index]
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    has = np.isfinite(np.diag(cov))
    std: dict[str, float | None] = {n: None for n in model.names}
    std.update({n: float(s) for n, s, h in zip(free, se, has) if h})
    sel = np.flatnonzero(has)
    c = cov[np.ix_(sel, sel)]
    s = se[sel]
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.clip(c / np.outer(s, s), -1.0, 1.0)
    np.fill_diagonal(corr, 1.0)
    return Uncertainty(std, [free[i] for i in sel], corr, method)


def standard_errors(engine: Engine, cs: CellSet, data: np.ndarray, values: np.ndarray, mats: np.ndarray,
                    at_bound: list[list[str]] | None = None, extra_hessian: np.ndarray | None = None,
                    stride: int | None = None) -> list[Uncertainty]:
    """Uncertainty of each fit: ``values`` (n, n_params) natural, fitted to materials ``mats`` of
    the cell set ``cs``, whose values at ``cs.index`` are ``data`` (materials of cs, channels, cells).
    ``at_bound``: names held at a bound per fit; ``extra_hessian`` (n, k, k): a penalty's
    Gauss-Newton Hessian in natural units; ``stride``: sum M by the float64 reference on every
    stride-th cell (default: by the engine over every cell where its program has the kernel).  One
    jtj and one meat launch for all fits."""
    model = engine.model
    values = np.atleast_2d(np.asarray(values, dtype=np.float64))
    n = values.shape[0]
    _, _, H = engine.jtj(cs, values, mats)
    if extra_hessian is not None:
        H = H + extra_hessian
    mats = np.broadcast_to(np.asarray(mats), (n,))
    if stride is None and engine.has_meat:
        M = engine.meat(cs, values, mats)
    else:
        stride = stride or meat_stride(cs.index.size)
        M = meat(model, cs.index, data, values, metric=engine.opt.metric, cosw=engine.opt.cosw, stride=stride,
                 rows=mats, cs=cs)
    free = [model.names[i] for i in model.free_index]
    out = []
    for i in range(n):
        held = set(at_bound[i]) if at_bound is not None else set()
        keep = np.array([f not in held for f in free], dtype=bool)
        cov = sandwich(H[i], M[i], keep)
        out.append(from_covariance(model, cov, method_line(stride, extra_hessian is not None)))
    return out
