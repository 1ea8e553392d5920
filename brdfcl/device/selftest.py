"""Known-answer test of a compiled program against the float64 reference.

A compiler that targets less than the device reports (PoCL's pip build on a Zen 4
reports AVX-512 widths but compiles for znver3) or a broken kernel-cache entry
gives a program that builds and runs but computes garbage, or none of it.  So each
program is checked once per process before it is trusted: every kernel (predict,
loss, grad, jtj, errors, meat) on a few hundred table cells, at two parameter vectors,
against `Model.reference` in float64.  Cheap (milliseconds), and independent of
the engine's internals: it only uses its public launches.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdfcl.data.geometry import N_CELLS as TABLE_CELLS
from brdfcl.data.geometry import cells_geometry
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.metrics import transform

N_CELLS = 384                    # a multiple of every vector width
TOLERANCE = {"float": 1e-4, "double": 1e-9}   # measured: 5e-7 and 1e-15 on a sound program


@dataclass(frozen=True)
class SelfTest:
    ok: bool
    max_error: float             # largest relative error over the kernels' outputs
    detail: str                  # which output failed, or a summary

    def __str__(self):
        return (f"passed (max relative error {self.max_error:.1e})" if self.ok
                else f"FAILED: {self.detail}")


def _cells(cutoff_deg=80.0):
    """(index, geometry) of N_CELLS valid table cells spread over the table, the specular peak's
    first cells included; from the geometry of a few thousand cells, not of the whole table."""
    def valid(index):
        return index[cells_geometry(index).mask(cutoff_deg)]
    near = valid(np.arange(8 * N_CELLS))
    spread = valid(np.arange(0, TABLE_CELLS, TABLE_CELLS // (8 * N_CELLS)))
    pick = np.unique(np.concatenate([near[:N_CELLS // 4], spread[:: max(1, spread.size // (3 * N_CELLS // 4))]]))
    pick = pick[:N_CELLS]
    return pick, cells_geometry(pick)


def _reference(model, cells, meas, w, values, metric, cosw):
    """Predictions, loss, gradient, J^T W r and the meat sum_cells w^2 g g^T (g = sum_ch r u) of one
    parameter vector in float64."""
    p, J = model.reference(cells, values)
    cw = cells.ci if cosw else np.ones_like(cells.ci)
    gp, dg = transform(metric, p * cw)
    r = gp - transform(metric, meas * cw)[0]
    u = (dg * cw)[..., None] * J
    g = np.einsum("cn,cnk->nk", r, u)
    return (p, float(np.sum(w * r * r)), 2 * np.einsum("cn,cnk->k", w * r, u), np.einsum("cn,cnk->k", w * r, u),
            np.einsum("n,nk,nl->kl", w * w, g, g))


def _rel(a, b):
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        return np.inf
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def check(engine) -> SelfTest:
    """Run every kernel of ``engine`` on known data and compare with the float64 reference."""
    model, opt = engine.model, engine.opt
    idx, geometry = _cells()
    cells = Cells.from_geometry(geometry)
    w = geometry.weight
    lo, hi = model.search_x_lo, model.search_x_hi
    values = np.stack([model.defaults(), model.from_x(lo + 0.37 * (hi - lo))])
    truth = model.reference(cells, model.from_x(lo + 0.61 * (hi - lo)), jacobian=False)
    ripple = 1 + 0.2 * np.sin(np.arange(idx.size))            # residuals that are not zero
    meas = truth * ripple
    cs = engine.upload_cells(["selftest"], [cells], [w], [meas.astype(engine.dtype)])
    meas = meas.astype(engine.dtype).astype(np.float64)      # what the device holds
    mats = np.zeros(len(values), dtype=np.int32)
    tol = TOLERANCE[opt.real]
    try:
        P = engine.predict(cs, values)
        L, G = engine.grad(cs, values, mats)
        L2, JTr, _ = engine.jtj(cs, values, mats)
        E = engine.errors(cs, values, mats)
        L3 = engine.loss(cs, values, mats)
        M = engine.meat(cs, values, mats) if engine.has_meat else None
    except Exception as e:  # a launch that fails is a failed test, reported in one line
        return SelfTest(False, np.inf, f"launch failed: {type(e).__name__}: {e}")
    worst, where = 0.0, ""
    for k, v in enumerate(values):
        p, lr, gr, jr, mr = _reference(model, cells, meas, w, v, opt.metric, opt.cosw)
        checks = {"predict": (P[k], p), "loss": (L3[k], lr), "grad loss": (L[k], lr), "grad": (G[k], gr),
                  "jtj loss": (L2[k], lr), "jtj J^T W r": (JTr[k], jr),
                  "errors": (E[f"rmse_{opt.metric}"][k] ** 2 * model.n_channels * np.sum(w), lr)}
        if M is not None:
            checks["meat"] = (M[k], mr)
        for name, (got, want) in checks.items():
            err = _rel(got, want)
            if not err <= worst:
                worst, where = err, f"{name} at parameter vector {k}"
    ok = worst <= tol
    detail = f"{where}: relative error {worst:.2e} (tolerance {tol:.0e})"
    return SelfTest(ok, worst, detail)
