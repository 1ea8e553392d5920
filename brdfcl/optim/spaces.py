"""The three spaces a model's parameters live in, and the maps between them.

* natural values ``v`` (all parameters, fixed ones included): what the kernels, the reference and
  the results use;
* the optimiser's ``x`` (free parameters, log of those flagged ``log``): the global search's box,
  and what the stages return;
* Levenberg-Marquardt's ``y``: ``x`` with the amplitudes back in natural units.  The model is
  linear in its amplitudes, so Gauss-Newton is exact in them, and an amplitude at its lower bound
  is not stuck on the flat of a log scale; shapes (alpha, a, ...) stay in log space.
"""
from __future__ import annotations

import numpy as np

from brdfcl.model.compose import Model


class Spaces:
    """Maps between ``v``, ``x`` and ``y`` for one model, and the bounds in each."""

    def __init__(self, model: Model):
        self.model = model
        free = model.free_index
        self.linear = model.amplitude[free] & model.log[free]    # columns where y = exp(x)

    # natural <-> optimiser
    def values(self, x: np.ndarray) -> np.ndarray:
        """Natural value vectors (fixed parameters at their values) from optimiser vectors."""
        return self.model.from_x(x)

    def to_x(self, values: np.ndarray) -> np.ndarray:
        return self.model.to_x(values)

    def dv_dx(self, values: np.ndarray) -> np.ndarray:
        """d v / d x of the free parameters at ``values`` (the chain rule of the log map)."""
        return self.model.dvalue_dx(values)

    # optimiser <-> Levenberg-Marquardt
    def to_y(self, x: np.ndarray) -> np.ndarray:
        y = np.array(x, dtype=np.float64)
        y[..., self.linear] = np.exp(y[..., self.linear])
        return y

    def from_y(self, y: np.ndarray) -> np.ndarray:
        x = np.array(y, dtype=np.float64)
        x[..., self.linear] = np.log(np.maximum(x[..., self.linear], 1e-300))
        return x

    def dv_dy(self, values: np.ndarray) -> np.ndarray:
        """d v / d y of the free parameters at ``values``."""
        return np.where(self.linear, 1.0, self.dv_dx(values))

    # bounds
    @property
    def x_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.model.x_lo, self.model.x_hi

    @property
    def y_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.to_y(self.model.x_lo), self.to_y(self.model.x_hi)

    @property
    def search_box(self) -> tuple[np.ndarray, np.ndarray]:
        """The global search's candidate box in x (each parameter's search range)."""
        return self.model.search_x_lo, self.model.search_x_hi

    def default_x(self, n: int) -> np.ndarray:
        """(n, k) copies of the model's default values in x."""
        return np.tile(self.to_x(self.model.defaults()), (n, 1))
