"""The loss a fit minimises: the kernels' data term plus every penalty, in each parameter space.

``loss = sum_cells w sum_ch r^2 (the kernels) + sum of penalties``.  The only penalty today is the
peak order (brdfcl.optim.peak_order), a residual vector per material scaled by the material's
summed cell weights, so that it is on the scale of its loss.  It enters every form of the loss
(value, gradient in x, Gauss-Newton terms in y) in one place, `Objective._add_penalties`.

The peak constraint makes the global search harder in two ways: with it, most Sobol candidates are
infeasible and the feasible ones favour needle-sharp CT lobes; without it (the search's
``penalty=False``, ``FitOptions.ct_peak_global=False``) the optima may have the lobes' roles
swapped, and walking them to the constraint can end in a poor local minimum.
brdfcl.analysis.analyze fits both ways.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdfcl.data.geometry import table_geometry
from brdfcl.device.engine import CellSet, Engine
from brdfcl.model.compose import Model
from brdfcl.optim.peak_order import PeakOrder
from brdfcl.optim.spaces import Spaces


def penalty_scale(index: np.ndarray, data: np.ndarray) -> np.ndarray:
    """Per material, the summed weight of its measured cells over all channels (``data`` (n_mat,
    C, cells) at the table cells ``index``, NaN: missing): the penalties' scale."""
    w = table_geometry().weight[index]
    return np.array([np.sum(np.isfinite(d) * w) for d in data])


@dataclass(frozen=True)
class Target:
    """What a loss is evaluated on: a cell set on the device, and each of its materials' penalty
    scale (from the full table, also for a coarse set, so that penalties weigh the same in every
    stage)."""

    cells: CellSet
    scale: np.ndarray


@dataclass
class Terms:
    """A loss (n,) and, where asked for, its gradient or Gauss-Newton terms in one space."""

    loss: np.ndarray
    grad: np.ndarray | None = None      # (n, k) d loss / dz
    jtr: np.ndarray | None = None       # (n, k) J^T W r
    jtj: np.ndarray | None = None       # (n, k, k) J^T W J


class Objective:
    """The penalised loss of one model on one engine, in the spaces of `Spaces`."""

    def __init__(self, engine: Engine, model: Model | None = None, peak_order: bool = False):
        self.engine = engine
        self.model: Model = engine.model if model is None else model    # the engine's, or an equal one
        self.spaces = Spaces(self.model)
        self.peak_order = PeakOrder.for_model(self.model) if peak_order else None

    @property
    def penalised(self) -> bool:
        return self.peak_order is not None

    # --- the one place penalties are added --------------------------------------------------------
    def _add_penalties(self, t: Terms, values: np.ndarray, scale: np.ndarray, dz: np.ndarray | None) -> Terms:
        """Add each penalty's ``sum r^2`` to ``t.loss`` and, where ``t`` has them, its gradient and
        Gauss-Newton terms in the space whose ``dv/dz`` is ``dz``."""
        if self.peak_order is None:
            return t
        r, J = self.peak_order.residual(values, scale)
        t.loss = t.loss + np.sum(r * r, axis=1)
        if t.grad is not None:
            t.grad = t.grad + 2 * np.einsum("nc,nck->nk", r, J) * dz
        if t.jtr is not None and t.jtj is not None:
            Jz = J if dz is None else J * dz[:, None, :]
            t.jtr = t.jtr + np.einsum("nc,nck->nk", r, Jz)
            t.jtj = t.jtj + np.einsum("nci,ncj->nij", Jz, Jz)
        return t

    # --- the loss in each space ---------------------------------------------------------------------
    def loss(self, target: Target, x: np.ndarray, mats: np.ndarray, penalty: bool = True) -> np.ndarray:
        """Loss (n,) at optimiser vectors ``x`` (n, k) of materials ``mats`` of ``target``."""
        v = self.spaces.values(x)
        t = Terms(self.engine.loss(target.cells, v, mats))
        if penalty:
            t = self._add_penalties(t, v, target.scale[mats], None)
        return t.loss

    def loss_grad(self, target: Target, x: np.ndarray, mats: np.ndarray,
                  penalty: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(loss (n,), gradient in x (n, k)) at optimiser vectors ``x``."""
        v = self.spaces.values(x)
        L, g = self.engine.grad(target.cells, v, mats)
        dv = self.spaces.dv_dx(v)
        t = Terms(L, grad=g * dv)
        if penalty:
            t = self._add_penalties(t, v, target.scale[mats], dv)
        assert t.grad is not None
        return t.loss, t.grad

    def jtj(self, target: Target, y: np.ndarray, mats: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(loss, J^T W r, J^T W J) in Levenberg-Marquardt's space ``y``, penalties included (the
        callback of brdfcl.optim.lm)."""
        v = self.spaces.values(self.spaces.from_y(y))
        L, r, H = self.engine.jtj(target.cells, v, mats)
        s = self.spaces.dv_dy(v)
        t = Terms(np.array(L, dtype=np.float64), jtr=r * s, jtj=H * s[:, :, None] * s[:, None, :])
        t = self._add_penalties(t, v, target.scale[mats], s)
        assert t.jtr is not None and t.jtj is not None
        return t.loss, t.jtr, t.jtj

    def penalty_hessian(self, values: np.ndarray, scale: np.ndarray) -> np.ndarray | None:
        """The penalties' Gauss-Newton Hessian (n, k, k) in natural units at ``values`` (n,
        n_params), None without penalties (brdfcl.optim.uncertainty adds it to the data's)."""
        if not self.penalised:
            return None
        n, k = values.shape[0], self.model.n_free
        t = Terms(np.zeros(n), jtr=np.zeros((n, k)), jtj=np.zeros((n, k, k)))
        return self._add_penalties(t, values, scale, None).jtj
