"""A fitted model at a Plan's points (brdfcl.report.view.views), for many materials at once.

With a compiled Engine of the model the values come from its ``predict`` kernel, every material
of the model in one launch over the plan's direction pairs and environment cells (float32, as
the fit itself evaluates, and sent on so); without one, from the model's float64 reference
(brdfcl.model).
The lobes one by one are evaluated on the in-plane slices only, where the report draws them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdfcl.data.geometry import table_geometry
from brdfcl.model.lobes.cells import Cells

CHUNK = 16                        # materials per launch: ~3 MB of results each


@dataclass
class Fitted:
    """One material's fitted values: at the plan's ``cells`` (3, n), at its ``env_cells``
    (3, m), and per lobe prefix at the in-plane slices (3, k); in float32 from the engine (half
    the bytes to send to an image worker; the images take them as they are), float64 from the
    reference."""

    points: np.ndarray
    env: np.ndarray
    lobes: dict


def _concat(parts):
    return Cells(*(np.concatenate([getattr(c, f) for c in parts]) for f in ("sh", "ch", "cd", "ci", "co")))


def _subset(cells, sel):
    return Cells(*(getattr(cells, f)[sel] for f in ("sh", "ch", "cd", "ci", "co")))


class Evaluator:
    """Evaluates fits of one model at a plan's points; ``engine`` None: the float64 reference."""

    def __init__(self, plan, model, engine=None):
        self.plan, self.model, self.engine = plan, model, engine
        env = Cells.from_geometry(table_geometry(), plan.env_cells)
        self.all = _concat([plan.cells, env])
        self.n_points = len(plan.cells)
        self.in_plane = _subset(plan.cells, plan.in_plane)
        if engine is not None:
            self._sets = [self._upload(self.all), self._upload(self.in_plane)]

    def _upload(self, cells):
        n = len(cells)
        return self.engine.upload_cells(["report"], [cells], [np.ones(n)],
                                          [np.zeros((self.model.n_channels, n))])

    def _at(self, which, values):
        """Model values (len(values), C, n) at cell set ``which`` (0: all points, 1: in plane)."""
        values = np.atleast_2d(np.asarray(values, dtype=np.float64))
        if self.engine is not None:
            return np.concatenate([self.engine.predict(self._sets[which], values[s:s + CHUNK], 0)
                                   for s in range(0, len(values), CHUNK)])
        cells = (self.all, self.in_plane)[which]
        return np.stack([self.model.reference(cells, v, jacobian=False) for v in values])

    def __call__(self, values_list) -> list[Fitted]:
        """The Fitted of each parameter vector in ``values_list``."""
        values = np.atleast_2d(np.asarray(values_list, dtype=np.float64))
        full = self._at(0, values)
        lobes = self.model.lobes
        only = [self.model.only_lobes(self.model.as_dict(v), (lb.prefix,)) for v in values for lb in lobes]
        parts = self._at(1, np.asarray(only)) if only else np.zeros((0,))
        out = []
        for i in range(len(values)):
            per = {lb.prefix: parts[i * len(lobes) + j] for j, lb in enumerate(lobes)}
            out.append(Fitted(full[i][:, :self.n_points], full[i][:, self.n_points:], per))
        return out
