"""What a fit is worth: standard errors and correlations of its parameters, the directional albedo
of the fitted model, and flags for values a user should not trust (issue 17).

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
as the independent units: exactly what a bootstrap over cells measures.  Measured on synthetic
diffuse+GGX materials with 2% multiplicative noise (tests/test_uncertainty.py has the figures),
the sandwich's standard errors are 0.83-1.17 times the spread of bootstrap refits per parameter,
while the homoscedastic form gives 0.07-0.13 times it for the specular parameters (0.7-1.4 for
the diffuse ones) and ``sigma^2 H^-1`` 0.5-2.4 times.

``H`` comes from the kernels (``Engine.jtj``, full table, one launch for all materials finishing
together), plus the Gauss-Newton Hessian of the peak-order penalty when the fit has one (it is a
constraint, not data, so it enters H and not M).  ``M`` needs the residual of every cell, which
the kernels only return summed, so it is computed with the float64 reference on a systematic
subsample of the fitted cells (every ``stride``-th in table order, at most ``MEAT_CELLS`` cells,
scaled by the stride): on the full table (910k cells) every 46th, whose standard errors are
within 6% of those of every cell for GGX lobes of alpha 0.1, 0.01 and 1e-3.  Measured cost: 3-5%
of a fit (0.025 s per material on 2 cores).  Parameters at a bound are held (their rows and
columns are left out: standard errors conditional on them) and get no standard error (None, JSON
null), as do fixed parameters.  All values are in natural units (not the optimiser's log space); for a
log-flagged parameter ``std_error / value`` is the standard error of its logarithm.  A residual
that is systematic (a model that does not fit) is treated as noise of independent cells; the
errors then say how much the fit depends on which cells were measured, not how far the model
is from the truth.

Directional albedo
------------------
``a(theta_i) = int f(wi, wo) cos theta_o dwo`` per channel, integrated over the half vector:
``wo = 2 (wi.h) h - wi``, ``dwo = 4 (wi.h) dwh``.  Every lobe of the model family (diffuse,
diffraction, Cook-Torrance) is centred on ``h = n`` whatever ``wi``, so a grid in ``(theta_h,
phi_h)`` graded towards ``theta_h = 0`` resolves lobes of any width: theta_h from 0 to the
horizon of ``wo`` (``tan 2 theta_h = -cos ti / (sin ti cos phi_h)``, so no cell straddles it)
in ``ALBEDO_PANELS`` log-spaced panels down to 1e-7 of that range, ``ALBEDO_GAUSS``
Gauss-Legendre points each; phi_h on [0, pi] (the integrand is even in phi_h) by the midpoint
rule with ``ALBEDO_PHI`` points.  Float64 reference values (``Model.reference``) on cells built
from ``h`` directly (sin theta_h exact down to 1e-7 rad).  Checked: a Lambertian lobe gives rho
to 1e-6; a GGX lobe with F = 1, alpha = 1e-3 gives 0.99999 at normal incidence.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from brdfcl.data.geometry import table_geometry
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.metrics import transform

_log = logging.getLogger("brdfcl")

MEAT_CELLS = 20_000                     # cells for the sandwich's middle term (see module doc)
ALBEDO_THETA_DEG = (0.0, 30.0, 60.0, 75.0, 85.0)
ALBEDO_PANELS, ALBEDO_GAUSS, ALBEDO_PHI = 16, 5, 24
ALBEDO_LIMIT = 1.0 + 1e-3               # flag above: 1, plus the quadrature's error
RELATIVE_ERROR_LIMIT = 1.0              # flag a parameter whose standard error exceeds |value|


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
        mat = [[_num(c, 6) for c in row] for row in np.asarray(self.correlation)]
        return {"std_error": {k: _num(v) for k, v in self.std_error.items()},
                "correlation": {"names": list(self.names), "matrix": mat}, "method": self.method}


def _num(v, digits=None):
    if v is None or not np.isfinite(v):
        return None
    return float(round(float(v), digits)) if digits else float(v)


def meat_stride(n_cells):
    return max(1, math.ceil(n_cells / MEAT_CELLS))


def method_line(stride, penalty=False):
    nth = f"{stride}{'th' if 10 <= stride % 100 < 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(stride % 10, 'th')}"
    every = "every cell" if stride == 1 else f"every {nth} cell"
    return (f"sandwich H^-1 M H^-1 (HC0, cells independent): H = J^T W J on the fitted cells"
            f"{' plus the peak-order penalty' if penalty else ''}, M = sum w^2 (J^T r)(J^T r)^T over "
            f"{every} (float64 reference); natural units; parameters at a bound held fixed")


def meat(model, index, data, values, metric="log", cosw=True, stride=1, rows=None):
    """``M = sum_cells w^2 g g^T``, ``g = sum_ch r dr/dtheta`` (n, k, k) for each material, on every
    ``stride``-th of the cells ``index`` (table order) scaled by the stride.  ``data``: measured
    values at ``index`` (NaN: missing), (materials, 3, index.size); fit i is of material
    ``rows[i]`` (default i); ``values``: (n, n_params) natural."""
    sub, cells, w, cos_i = _subsample(index, stride)
    cw = cos_i if cosw else np.ones(sub.size)
    k = model.n_free
    out = np.zeros((len(values), k, k))
    w2 = w * w
    for i, v in enumerate(np.atleast_2d(values)):
        m = np.asarray(data[i if rows is None else rows[i]][:, sub], dtype=np.float64)
        ok = np.isfinite(m)
        p, J = model.reference(cells, v)
        gp, dg = transform(metric, p * cw)
        r = np.where(ok, gp - transform(metric, np.where(ok, m, 0.0) * cw)[0], 0.0)
        gc = np.zeros((sub.size, k))
        for c in range(3):
            gc += J[c] * (r[c] * dg[c] * cw)[:, None]
        gc = np.where(np.isfinite(gc), gc, 0.0)
        out[i] = stride * ((gc * w2[:, None]).T @ gc)
    return out


_SUBSAMPLES: dict = {}


def _subsample(index, stride):
    """(positions in index, Cells, weights, cos theta_i) of every stride-th cell, kept per index set."""
    key = (id(index), index.size, stride)            # the entry keeps index alive: ids stay unique
    if key not in _SUBSAMPLES or _SUBSAMPLES[key][0] is not index:
        g = table_geometry()
        sub = np.arange(stride // 2, index.size, stride)
        idx = index[sub]
        if len(_SUBSAMPLES) > 8:
            _SUBSAMPLES.clear()
        _SUBSAMPLES[key] = (index, sub, Cells.from_geometry(g, idx), g.weight[idx], g.cos_i[idx])
    return _SUBSAMPLES[key][1:]


def sandwich(H, M, keep):
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


def from_covariance(model, cov, method) -> Uncertainty:
    free = [model.names[i] for i in model.free_index]
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    has = np.isfinite(np.diag(cov))
    std = {n: None for n in model.names}
    std.update({n: float(s) for n, s, h in zip(free, se, has) if h})
    sel = np.flatnonzero(has)
    c = cov[np.ix_(sel, sel)]
    s = se[sel]
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.clip(c / np.outer(s, s), -1.0, 1.0)
    np.fill_diagonal(corr, 1.0)
    return Uncertainty(std, [free[i] for i in sel], corr, method)


def standard_errors(engine, cs, data, values, mats, at_bound=None, extra_hessian=None, stride=None):
    """Uncertainty of each fit: ``values`` (n, n_params) natural, fitted to materials ``mats`` of
    the cell set ``cs``, whose values at ``cs.index`` are ``data`` (materials of cs, 3, cells).
    ``at_bound``: names held at a bound per fit; ``extra_hessian`` (n, k, k): a penalty's
    Gauss-Newton Hessian in natural units.  One jtj launch for all fits."""
    model = engine.model
    values = np.atleast_2d(np.asarray(values, dtype=np.float64))
    n = values.shape[0]
    stride = stride or meat_stride(cs.index.size)
    _, _, H = engine.jtj(cs, values, mats)
    if extra_hessian is not None:
        H = H + extra_hessian
    mats = np.broadcast_to(np.asarray(mats), (n,))
    M = meat(model, cs.index, data, values, engine.opt.metric, engine.opt.cosw, stride, rows=mats)
    free = [model.names[i] for i in model.free_index]
    out = []
    for i in range(n):
        held = set(at_bound[i]) if at_bound is not None else set()
        keep = np.array([f not in held for f in free], dtype=bool)
        cov = sandwich(H[i], M[i], keep)
        out.append(from_covariance(model, cov, method_line(stride, extra_hessian is not None)))
    return out


# --- directional albedo -------------------------------------------------------------------------
def albedo_cells(theta_i):
    """Quadrature of the outgoing hemisphere for incidence theta_i (rad): (Cells, weights) with
    ``sum(weights * f * cos theta_o) = a(theta_i)`` (see module doc)."""
    si, ci = math.sin(theta_i), math.cos(theta_i)
    phi = (np.arange(ALBEDO_PHI) + 0.5) * math.pi / ALBEDO_PHI
    w_phi = 2.0 * math.pi / ALBEDO_PHI                           # [0, pi], doubled
    t_max = 0.5 * np.arctan2(ci, -si * np.cos(phi))               # wo on the horizon
    x, wx = np.polynomial.legendre.leggauss(ALBEDO_GAUSS)
    edges = np.concatenate([[0.0], np.geomspace(1e-7, 1.0, ALBEDO_PANELS)])
    a, b = edges[:-1, None], edges[1:, None]
    u = (0.5 * (b - a) * (x + 1) + a).ravel()                     # in (0, 1), graded towards 0
    wu = (0.5 * (b - a) * wx).ravel()
    th = t_max[:, None] * u[None, :]
    dth = t_max[:, None] * wu[None, :]
    P = np.broadcast_to(phi[:, None], th.shape)
    sh, ch = np.sin(th), np.cos(th)
    cd = si * sh * np.cos(P) + ci * ch                            # wi . h
    co = 2.0 * cd * ch - ci                                       # wo . n
    cells = Cells(sh.ravel(), ch.ravel(), cd.ravel(), np.full(th.size, ci), co.ravel())
    weight = (4.0 * cd * sh * dth * w_phi).ravel()                # dwo = 4 (wi.h) sin th dth dphi
    return cells, weight


def directional_albedo(model, values, theta_i_deg=ALBEDO_THETA_DEG):
    """Directional albedo (n, angles, 3) of the model at each value vector (n, n_params)."""
    values = np.atleast_2d(np.asarray(values, dtype=np.float64))
    out = np.zeros((values.shape[0], len(theta_i_deg), 3))
    for j, t in enumerate(theta_i_deg):
        cells, wq = albedo_cells(math.radians(t))
        wq = wq * np.maximum(cells.co, 0.0)
        for i, v in enumerate(values):
            p = model.reference(cells, v, jacobian=False)
            out[i, j] = np.sum(np.where(np.isfinite(p), p, 0.0) * wq, axis=1)
    return out


def albedo_json(albedo_row, theta_i_deg=ALBEDO_THETA_DEG) -> dict:
    return {"theta_i_deg": [float(t) for t in theta_i_deg],
            "channels": [[_num(a) for a in row] for row in albedo_row]}


# --- flags ---------------------------------------------------------------------------------------
def flags(model, values, at_bound=(), unc: Uncertainty | None = None, albedo_row=None,
          theta_i_deg=ALBEDO_THETA_DEG) -> list:
    """One line per reason not to take a fit at face value: energy conservation broken (albedo above
    1 in a channel), parameters at a bound, parameters the data leave undetermined."""
    out = []
    if albedo_row is not None:
        a = np.asarray(albedo_row, dtype=np.float64)
        a = np.where(np.isfinite(a), a, np.inf)
        if (a > ALBEDO_LIMIT).any():
            j, c = np.unravel_index(np.argmax(a), a.shape)
            angles = [f"{theta_i_deg[t]:g}" for t in range(a.shape[0]) if (a[t] > ALBEDO_LIMIT).any()]
            out.append(f"non-physical: directional albedo above 1 (up to {a[j, c]:.4g} in channel "
                       f"{'rgb'[c]} at theta_i {theta_i_deg[j]:g} deg; above 1 at {', '.join(angles)} deg): "
                       f"the fit reflects more energy than it receives")
    v = np.asarray(values, dtype=np.float64)
    for name in at_bound:
        i = model.names.index(name)
        lo, hi = model.lo[i], model.hi[i]
        side = "lower" if abs(v[i] - lo) <= abs(hi - v[i]) else "upper"
        out.append(f"{name} = {v[i]:.4g} at its {side} bound {lo if side == 'lower' else hi:g} "
                   f"(no standard error)")
    if unc is not None:
        for name, s in unc.std_error.items():
            val = v[model.names.index(name)]
            if s is not None and s > RELATIVE_ERROR_LIMIT * abs(val):
                out.append(f"{name} = {val:.4g} poorly determined: standard error {s:.3g} exceeds its value")
    return out


def bounds_hit(model, x):
    """Free parameters at a bound in the optimiser's space x: the rule of Fitter.fit's bounds_hit."""
    return [model.names[k] for k, xx, a, b in zip(model.free_index, x, model.x_lo, model.x_hi)
            if min(xx - a, b - xx) <= 1e-6 * max(1.0, abs(b - a))]


# --- what Fitter.fit attaches to each result --------------------------------------------------------
def assess(fitter, cs, data, values, rows, at_bound):
    """{"uncertainty", "albedo", "flags"} (NAME.json form) for the fits ``values`` (natural) of the
    materials ``rows`` of the Fitter's full cell set ``cs`` (``data``: every material's values
    there), ``at_bound`` the names at a bound per fit.  One jtj launch for all of them.  A failure
    here never costs the fits: they get a flag saying why they were not assessed."""
    try:
        return _assess(fitter, cs, data, values, rows, at_bound)
    except Exception as e:          # noqa: BLE001 - a diagnostic must not lose a finished fit
        _log.warning(f"brdfcl: uncertainty not computed: {type(e).__name__}: {e}")
        return [{"uncertainty": None, "albedo": None,
                 "flags": [f"not assessed: {type(e).__name__}: {e}"]} for _ in rows]


def _assess(fitter, cs, data, values, rows, at_bound):
    model = fitter.model
    values = np.atleast_2d(np.asarray(values, dtype=np.float64))
    rows = np.asarray(rows)
    extra = None
    if fitter.order is not None:
        _, Jp = fitter.order.residual(values, fitter._sw[rows])
        extra = np.einsum("nci,ncj->nij", Jp, Jp)
    finite = np.isfinite(values).all(axis=1)
    unc = [None] * len(rows)
    if finite.any():
        sel = np.flatnonzero(finite)
        got = standard_errors(fitter.engine, cs, data, values[sel], rows[sel],
                              [at_bound[j] for j in sel], None if extra is None else extra[sel])
        for j, u in zip(sel, got):
            unc[j] = u
    alb = directional_albedo(model, np.where(finite[:, None], values, model.defaults()))
    out = []
    for j in range(len(rows)):
        if not finite[j]:
            out.append({"uncertainty": None, "albedo": None,
                        "flags": ["not assessed: non-finite parameters"]})
            continue
        out.append({"uncertainty": unc[j].as_json(), "albedo": albedo_json(alb[j]),
                    "flags": flags(model, values[j], at_bound[j], unc[j], alb[j])})
    return out
