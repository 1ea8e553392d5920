"""Lambertian lobe: p = rho_d / pi."""
from __future__ import annotations

import numpy as np

from brdfcl.model.lobes.lobe import Lobe
from brdfcl.model.lobes.spec import Param

RHO_D = Param("rho", 1e-6, 1.0, 0.1, log=True, per_channel=True, doc="diffuse albedo", search=(1e-3, 1.0))


class Diffuse(Lobe):
    prefix = "diffuse"
    role = "diffuse"
    amplitude = RHO_D

    def spec(self):
        return "diffuse"

    def reference(self, cells, value, consts):
        vals, jacs = [], []
        for ch in range(3):
            rho = self.slot_name("rho", ch)
            vals.append(np.full(len(cells), value(rho) / np.pi))
            jacs.append({rho: np.full(len(cells), 1.0 / np.pi)})
        return vals, jacs

    def emit(self, em, ctx):
        for ch in range(3):
            rho = self.slot_name("rho", ch)
            em.add(ch, f"{ctx.c(rho)} * INV_PI_R")
            em.add_jac(ch, rho, "INV_PI_R")
