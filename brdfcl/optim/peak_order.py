"""Which lobe carries the specular peak: Cook-Torrance, as in the talk's three-lobe model.

Cook-Torrance and diffraction fit the same tables (GGX's D and the hp PSD are the same
function of sin theta_h at theta_d = 0), so a free fit of both may swap their roles: a
broad CT lobe for the wide angles and a narrow diffraction lobe on the peak.  The talk's
model gives each lobe one region, and this makes it a constraint of the fit: at the
specular peak (`peak_cell`), in every channel, the diffraction lobes' summed value may not
exceed the reflection (CT) lobes',

    ln W_c(peak) - ln C_c(peak) <= 0,

imposed as a quadratic penalty ``WEIGHT * sum_w * sum_c max(0, ln W_c - ln C_c)^2``
(sum_w: the material's summed cell weights, so that the penalty is on the scale of its
loss; a 1% excess costs as much as an rmse of 0.01).  The lobe values and their
derivatives come from the float64 reference of each lobe, one row per material.
`brdfcl analyze` reports what the constraint costs (the full fit with and without it).
"""
from __future__ import annotations

import numpy as np

from brdfcl.data.geometry import bin_centres, directions
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells

WEIGHT = 1.0
PEAK_TD_BIN = 10          # theta_d ~ 10 deg on the first theta_h bin, phi_d ~ 90 deg


def peak_cell(n: int = 1) -> Cells:
    """n copies of the cell that stands for the specular peak."""
    th, td, pd = bin_centres()
    wi, wo = directions(np.full(n, th[0]), np.full(n, td[PEAK_TD_BIN]), np.full(n, pd[90]))
    return Cells.from_directions(wi, wo)


def lobe_model(model: Model, role: str) -> Model | None:
    """The sub-model made of the lobes of ``model`` that play ``role`` (same parameter names), or
    None when there is none."""
    return model.submodel(model.lobes_with_role(role))


class PeakOrder:
    """The penalty for one model, on natural parameter vectors (rows = materials)."""

    def __init__(self, model: Model, w_model: Model, c_model: Model):
        self.model, self.w, self.c = model, w_model, c_model
        free = [model.names[i] for i in model.free_index]
        self._cols = {sub: np.array([free.index(sub.names[i]) for i in sub.free_index], dtype=int)
                      for sub in (w_model, c_model)}
        self._pick = {sub: np.array([model.names.index(n) for n in sub.names]) for sub in (w_model, c_model)}

    @classmethod
    def for_model(cls, model: Model) -> PeakOrder | None:
        """The penalty for a model with diffraction and reflection (Cook-Torrance) lobes, else None."""
        w, c = lobe_model(model, "diffraction"), lobe_model(model, "reflection")
        return cls(model, w, c) if w is not None and c is not None else None

    def _lobe(self, sub, values):
        p, J = sub.reference(peak_cell(values.shape[0]), values[:, self._pick[sub]])
        return p.T, np.moveaxis(J, 0, 1)          # (n, C), (n, C, sub free)

    def _log_ratio(self, values, jacobian=True):
        """ln W_c - ln C_c at the peak (n, C) and its Jacobian (n, C, n_free)."""
        values = np.atleast_2d(np.asarray(values, dtype=np.float64))
        (W, JW), (C, JC) = self._lobe(self.w, values), self._lobe(self.c, values)
        W, C = np.maximum(W, 1e-300), np.maximum(C, 1e-300)
        if not jacobian:
            return np.log(W) - np.log(C), None
        J = np.zeros(W.shape + (self.model.n_free,))
        J[:, :, self._cols[self.w]] += JW / W[..., None]
        J[:, :, self._cols[self.c]] -= JC / C[..., None]
        return np.log(W) - np.log(C), J

    def residual(self, values: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (n, C) and their Jacobian (n, C, n_free) w.r.t. the free natural parameters."""
        v, J = self._log_ratio(values)
        s = np.sqrt(WEIGHT * np.asarray(scale, dtype=np.float64))[:, None]
        on = (v > 0) & np.isfinite(v)
        r = np.where(on, s * np.minimum(v, 50.0), 0.0)
        J *= np.where(on, s, 0.0)[..., None]
        return r, np.where(np.isfinite(J), J, 0.0)

    def loss(self, values: np.ndarray, scale: np.ndarray) -> np.ndarray:
        """The penalty (n,): sum of the squared residuals."""
        r, _ = self.residual(values, scale)
        return np.sum(r * r, axis=1)

    def excess(self, values: np.ndarray) -> np.ndarray:
        """ln W_c - ln C_c at the peak (n, C): > 0 where diffraction carries more than CT."""
        return self._log_ratio(values, jacobian=False)[0]
