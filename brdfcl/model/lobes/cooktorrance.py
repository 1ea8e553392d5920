"""Cook-Torrance lobe: p = rho_s D(th) G(i, o) F(td) / (4 cos ti cos to) (docs/spec.md section 3)."""
from __future__ import annotations

from brdfcl.model.lobes.lobe import Factor, Known, Lobe
from brdfcl.model.terms import REGISTRY, Param, shadowing_for

RHO_S = Param("rho", 1e-6, 10.0, 0.5, log=True, per_channel=True, search=(1e-2, 5.0),
              doc="specular amplitude (times F; <= 1 for a physical surface)")
INV_4_CI_CO = Known("c.inv4cico", lambda cells: cells.inv4cico)


class CookTorrance(Lobe):
    prefix = "ct"
    role = "reflection"
    amplitude = RHO_S

    def __init__(self, ndf="ggx", shadowing=None, fresnel="schlick", lambdas=None):
        """``shadowing``: a family (``smith``, ``smith-hc``, ``vcavity``, ``none``; default ``smith``
        where the D has one, else ``vcavity``), the term of it defined for this D."""
        if lambdas is not None:
            self.lambdas = tuple(float(x) for x in lambdas)
        self.ndf = REGISTRY["ndf"][ndf]
        term = shadowing_for(ndf, shadowing) if shadowing is not None else (
            shadowing_for(ndf, "smith") or shadowing_for(ndf, "vcavity"))
        if term is None:
            defined = sorted({d for t in REGISTRY["shadowing"].values() if t.family == shadowing for d in t.ndfs})
            raise ValueError(f"shadowing '{shadowing}' is defined for {', '.join(defined)} only, not for '{ndf}'; "
                             f"use vcavity or none")
        self.shadowing = term
        self.fresnel = REGISTRY["fresnel"][fresnel]
        self.terms = (self.ndf, self.shadowing, self.fresnel)

    def spec(self):
        return f"{self.ndf.name}:{self.shadowing.family}:{self.fresnel.name}"

    def parts(self, ch):
        return INV_4_CI_CO, [Factor(self.ndf), Factor(self.shadowing),
                             Factor(self.fresnel, channel=ch if self.fresnel.per_channel else None)]
