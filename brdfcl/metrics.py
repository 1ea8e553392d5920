"""Error metrics (docs/spec.md section 4), float64 reference.

Residuals per valid cell and channel, with ``x = p * cw`` where ``cw`` is
cos(theta_i) (or 1 without the cosine factor):

* ``l2``:   r = x_model - x_measured
* ``log``:  r = ln(1 + x_model) - ln(1 + x_measured)
* ``cbrt``: r = cbrt(x_model + eps) - cbrt(x_measured + eps), eps = CBRT_EPS
  (the offset keeps the derivative finite where the model is 0)

The loss is sum(w r^2) over cells and channels, w the cell's solid-angle
weight.  Reported errors are weighted RMS values,
``rmse_M = sqrt(sum(w r_M^2) / (3 sum w))``, and ``rel_rmse = sqrt(sum(w r_l2^2) /
sum(w x_measured^2))``.  Sums are float64 (numpy's pairwise summation).
"""
from __future__ import annotations

import numpy as np

METRICS = ("l2", "log", "cbrt")
CBRT_EPS = 1e-4


def transform(metric, x):
    """g(x) and g'(x) of a metric."""
    if metric == "l2":
        return x, np.ones_like(x)
    if metric == "log":
        return np.log1p(x), 1.0 / (1.0 + x)
    if metric == "cbrt":
        c = np.cbrt(x + CBRT_EPS)
        return c, 1.0 / (3.0 * c * c)
    raise ValueError(f"unknown metric '{metric}'; valid: {', '.join(METRICS)}")


def check_metric(metric):
    if metric not in METRICS:
        raise ValueError(f"unknown metric '{metric}'; valid: {', '.join(METRICS)}")
    return metric


def errors(p, m, w, cw):
    """All reported errors of a prediction p against measurements m (both (3, n), NaN = missing)."""
    ok = np.isfinite(m) & np.isfinite(p)
    xm = np.where(ok, m * cw, 0.0)
    xp = np.where(ok, p * cw, 0.0)
    ww = np.where(ok, w, 0.0)
    out = {}
    for metric in METRICS:
        r = transform(metric, xp)[0] - transform(metric, xm)[0]
        out[f"rmse_{metric}"] = float(np.sqrt(np.sum(ww * r * r) / max(np.sum(ww), 1e-300)))
    out["rel_rmse"] = float(np.sqrt(np.sum(ww * (xp - xm) ** 2) / max(np.sum(ww * xm * xm), 1e-300)))
    return out


def loss_grad(model, cells, m, w, cw, values, metric="log"):
    """Loss sum(w r^2) and its gradient w.r.t. the free natural parameters (float64 reference)."""
    p, J = model.reference(cells, values)
    ok = np.isfinite(m)
    g_p, dg = transform(metric, p * cw)
    g_m = transform(metric, np.where(ok, m, 0.0) * cw)[0]
    ww = np.where(ok, w, 0.0)
    r = np.where(ok, g_p - g_m, 0.0)
    loss = float(np.sum(ww * r * r))
    grad = 2.0 * np.einsum("cn,cnk->k", ww * r * dg * cw, J)
    return loss, grad
