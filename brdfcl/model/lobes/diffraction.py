"""Diffraction lobe: p_c = rho_w,c / lambda_c^4 F(td) S(f_c), f_c = 2 sin th cos td / lambda_c.

The wavelength dependence comes only from lambda_c (docs/spec.md section 3); f is in 1/um.
"""
from __future__ import annotations

from brdfcl.model.lobes.lobe import LAMBDAS, Factor, Known, Lobe
from brdfcl.model.terms import REGISTRY, Param

RHO_W = Param("rho", 1e-8, 1e4, 0.01, log=True, per_channel=True, unit="um^4", search=(1e-5, 1.0),
              doc="diffraction amplitude (peak value times lambda^4)")

__all__ = ["LAMBDAS", "RHO_W", "Diffraction"]


class Diffraction(Lobe):
    prefix = "diffraction"
    role = "diffraction"
    amplitude = RHO_W

    def __init__(self, psd="hp", fresnel="none", lambdas=LAMBDAS):
        self.psd = REGISTRY["psd"][psd]
        self.fresnel = REGISTRY["fresnel"][fresnel]
        self.terms = (self.psd, self.fresnel)
        self.lambdas = tuple(float(x) for x in lambdas)

    def spec(self):
        return f"diffraction:{self.psd.name}:{self.fresnel.name}"

    def parts(self, ch):
        lam = self.lambdas[ch]
        f = Known("c.f0 * {k}", lambda cells: cells.f0 / lam, k=1.0 / lam)
        return (Known("{k}", lambda cells: lam ** -4, k=lam ** -4),
                [Factor(self.psd, arg=f, channel=ch),
                 Factor(self.fresnel, channel=ch if self.fresnel.per_channel else None)])
