"""Per-cell quantities that the lobes read, computed once from the geometry.

The same quantities are formed in the kernels' prologue (kernels/common.cl,
``make_cell``) from the stored ``sin th, cos th, cos td, cos ti, cos to``;
this is the float64 reference of that prologue.  sin th is stored rather than
derived so that tan^2 th keeps its precision at the peak in float32.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Cells:
    sh: np.ndarray   # sin theta_h
    ch: np.ndarray   # cos theta_h
    cd: np.ndarray   # cos theta_d
    ci: np.ndarray   # cos theta_i
    co: np.ndarray   # cos theta_o

    @classmethod
    def from_geometry(cls, geom, mask=None):
        sel = slice(None) if mask is None else mask
        return cls(np.sin(geom.theta_h[sel]), np.cos(geom.theta_h[sel]), np.cos(geom.theta_d[sel]),
                   geom.cos_i[sel], geom.cos_o[sel])

    @classmethod
    def from_directions(cls, wi, wo):
        """Cells for arbitrary direction pairs (n = z), for reciprocity and integration tests."""
        h = wi + wo
        h = h / np.linalg.norm(h, axis=-1, keepdims=True)
        ch = h[..., 2]
        sh = np.sqrt(np.maximum(1.0 - ch * ch, 0.0))
        cd = np.sum(wi * h, axis=-1)
        return cls(sh, ch, cd, wi[..., 2], wo[..., 2])

    @property
    def t2(self):
        """tan^2 theta_h."""
        return (self.sh / self.ch) ** 2

    @property
    def sd(self):
        return np.sqrt(np.maximum(1.0 - self.cd ** 2, 0.0))

    @property
    def f0(self):
        """Spatial frequency times wavelength: ||(i + o) x n|| = 2 sin th cos td."""
        return 2.0 * self.sh * self.cd

    @property
    def s5(self):
        """(1 - cos theta_d)^5, Schlick's factor."""
        return (1.0 - self.cd) ** 5

    @property
    def t2i(self):
        return (1.0 - self.ci ** 2) / self.ci ** 2

    @property
    def t2o(self):
        return (1.0 - self.co ** 2) / self.co ** 2

    @property
    def gv(self):
        """V-cavity shadowing/masking, parameter free."""
        return np.minimum(1.0, 2.0 * self.ch * np.minimum(self.ci, self.co) / self.cd)

    def astype(self, dtype):
        return Cells(*(np.asarray(a, dtype=dtype) for a in (self.sh, self.ch, self.cd, self.ci, self.co)))

    def __len__(self):
        return self.sh.size
