"""Lambertian lobe: p = rho_d / pi."""
from __future__ import annotations

import numpy as np

from brdfcl.model.lobes.lobe import Known, Lobe
from brdfcl.model.terms import Param

RHO_D = Param("rho", 1e-6, 1.0, 0.1, log=True, per_channel=True, doc="diffuse albedo", search=(1e-3, 1.0))
INV_PI = Known("INV_PI_R", lambda cells: 1.0 / np.pi)


class Diffuse(Lobe):
    prefix = "diffuse"
    role = "diffuse"
    amplitude = RHO_D

    def __init__(self, lambdas=None):
        if lambdas is not None:
            self.lambdas = tuple(float(x) for x in lambdas)

    def spec(self):
        return "diffuse"

    def parts(self, ch):
        return INV_PI, []
