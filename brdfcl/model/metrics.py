"""Error metrics (docs/spec.md section 4), float64 reference, and the metric registry.

Residuals per valid cell and channel, with ``x = p * cw`` where ``cw`` is
cos(theta_i) (or 1 without the cosine factor), are ``r = g(x_model) - g(x_measured)``
with ``g`` the metric's transform:

* ``l2``:   g(x) = x
* ``log``:  g(x) = ln(1 + x)
* ``cbrt``: g(x) = cbrt(x + eps), eps = CBRT_EPS
  (the offset keeps the derivative finite where the model is 0)

The loss is sum(w r^2) over cells and channels, w the cell's solid-angle
weight.  Reported errors are weighted RMS values,
``rmse_M = sqrt(sum(w r_M^2) / (3 sum w))`` for every registered metric M, and
``rel_rmse = sqrt(sum(w r_l2^2) / sum(w x_measured^2))``.  Sums are float64
(numpy's pairwise summation).

The registry
------------
``IMPLEMENTED_METRICS`` (in the manner of scipy.optimize's ``IMPLEMENTED_LOSSES``)
maps each metric name to a `Metric`: its numpy transform and derivative, the same
two as OpenCL C expressions, and a one-line doc.  Everything else reads this table:
`METRICS` (a live view of its names, in order), `check_metric`, `transform`,
`errors`, the CLI's ``--metric`` choices, and the kernel generator (brdfcl.kernels.codegen,
kernels/model.cl.mako), which writes ``metric_g`` / ``metric_dg`` for the fit metric
from the entry and accumulates ``sum w r_M^2`` for every entry in the ``errors``
kernel.  Adding a metric is one entry, in the table below (or, as the tests do, at
run time before an Engine is built)::

    IMPLEMENTED_METRICS["asinh"] = Metric(
        "asinh", g=np.arcsinh, dg=lambda x, g: 1 / np.sqrt(1 + x * x),
        c_g="asinh({x})", c_dg="rsqrt(1 + {x} * {x})",
        doc="g(x) = asinh(x), linear near 0 and logarithmic for large x")

``c_g`` is a C expression of ``{x}``; ``c_dg`` one of ``{x}`` and ``{g}`` (str.format
fields, so double any literal brace; ``{g}`` is g(x), already computed).  Both are
``real_v`` (float or double, scalar or vector): use OpenCL built-ins that take any
gentype, and write constants as ``(real)c`` or plain integers.  The name must be a C
identifier.  The new metric is then a fit metric (``--metric``,
``KernelOptions(metric=...)``), the engine's self-test checks its kernels against the
numpy g and g', and ``rmse_<name>`` appears among the reported errors (the summary CSV
keeps its fixed columns; the results JSON carries every error).
tests/test_metrics_registry.py registers such a metric at test time.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Callable

import numpy as np

CBRT_EPS = 1e-4


@dataclass(frozen=True)
class Metric:
    """One metric: g and g' in numpy (float64 reference) and as OpenCL C expressions."""
    name: str
    g: Callable[[np.ndarray], np.ndarray]                   # g(x)
    dg: Callable[[np.ndarray, np.ndarray], np.ndarray]      # g'(x), given x and g(x)
    c_g: str                                                # C expression of {x}
    c_dg: str                                               # C expression of {x} and {g}
    doc: str = ""

    def __post_init__(self):
        if not self.name.isidentifier():
            raise ValueError(f"metric name '{self.name}' is not a C identifier")

    def c(self, x, g=None):
        """(g, g') as C expressions of the C expressions ``x`` and ``g`` (default: g(x))."""
        return self.c_g.format(x=x), self.c_dg.format(x=x, g=self.c_g.format(x=x) if g is None else g)


IMPLEMENTED_METRICS: dict[str, Metric] = {
    "l2": Metric("l2", g=lambda x: x, dg=lambda x, g: np.ones_like(x),
                 c_g="{x}", c_dg="(real_v)1",
                 doc="g(x) = x, plain differences (dominated by the peaks)"),
    "log": Metric("log", g=np.log1p, dg=lambda x, g: 1.0 / (1.0 + x),
                  c_g="log1p({x})", c_dg="1 / (1 + {x})",
                  doc="g(x) = ln(1 + x), compresses the peaks"),
    "cbrt": Metric("cbrt", g=lambda x: np.cbrt(x + CBRT_EPS), dg=lambda x, g: 1.0 / (3.0 * g * g),
                   c_g=f"cbrt({{x}} + (real){CBRT_EPS!r})", c_dg="1 / (3 * {g} * {g})",
                   doc=f"g(x) = cbrt(x + {CBRT_EPS:g}), a cube root as in CIE lightness"),
}


class _MetricNames(Sequence):
    """The names in IMPLEMENTED_METRICS, in order: a live view, so that a metric registered
    later is valid wherever METRICS was imported (argparse choices included)."""

    def __getitem__(self, i):
        return tuple(IMPLEMENTED_METRICS)[i]

    def __len__(self):
        return len(IMPLEMENTED_METRICS)

    def __contains__(self, name):
        return name in IMPLEMENTED_METRICS

    def __iter__(self):
        return iter(tuple(IMPLEMENTED_METRICS))

    def __eq__(self, other):
        return isinstance(other, Sequence) and not isinstance(other, str) and tuple(self) == tuple(other)

    __hash__ = None  # type: ignore[assignment]  # equal to tuples, so not hashable

    def __repr__(self):
        return repr(tuple(self))


METRICS = _MetricNames()


def check_metric(metric):
    if metric not in IMPLEMENTED_METRICS:
        raise ValueError(f"unknown metric '{metric}'; valid: {', '.join(METRICS)}")
    return metric


def get_metric(metric) -> Metric:
    """The registry entry of a metric name."""
    return IMPLEMENTED_METRICS[check_metric(metric)]


def transform(metric, x):
    """g(x) and g'(x) of a metric."""
    m = get_metric(metric)
    g = m.g(x)
    return g, m.dg(x, g)


def errors(p, m, w, cw):
    """All reported errors of a prediction p against measurements m (both (3, n), NaN = missing):
    ``rmse_<name>`` for every registered metric, and ``rel_rmse``."""
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
