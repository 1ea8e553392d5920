"""Diffraction lobe: p_c = rho_w,c / lambda_c^4 F(td) S(f_c), f_c = 2 sin th cos td / lambda_c.

The wavelength dependence comes only from lambda_c (docs/spec.md section 3); f is in 1/um.
"""
from __future__ import annotations

from brdfcl.model.lobes.lobe import Lobe
from brdfcl.model.lobes.spec import REGISTRY, Param

RHO_W = Param("rho", 1e-8, 1e4, 0.01, log=True, per_channel=True, unit="um^4", search=(1e-5, 1.0),
              doc="diffraction amplitude (peak value times lambda^4)")
LAMBDAS = (0.645, 0.526, 0.444)
"""Default wavelengths (um) of the R, G, B channels."""


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

    def reference(self, cells, value, consts):
        f0 = cells.f0
        Fs = None if self.fresnel.per_channel else self.ref_term(self.fresnel, cells, value, consts)
        vals, jacs = [], []
        for ch, lam in enumerate(self.lambdas):
            S, dS = self.ref_term(self.psd, f0 / lam, value, consts)
            F, dF = Fs or self.ref_term(self.fresnel, cells, value, consts, ch)
            rho_name = self.slot_name("rho", ch)
            scale = value(rho_name) / lam ** 4
            vals.append(scale * F * S)
            jac = {rho_name: F * S / lam ** 4}
            jac.update({k: scale * F * d for k, d in dS.items()})
            jac.update({k: scale * S * d for k, d in dF.items()})
            jacs.append(jac)
        return vals, jacs

    def emit(self, em, ctx):
        shared = None if self.fresnel.per_channel else self.emit_term(em, self.fresnel, "&c", "")
        dr = "dr" + self.tag                # C names: dr_f_0, dr_scale_0 (dr2_... for a second lobe)
        for ch, lam in enumerate(self.lambdas):
            em.line(f"const real_v {dr}_f_{ch} = c.f0 * (real){1.0 / lam!r};")
            S, dS = self.emit_term(em, self.psd, f"{dr}_f_{ch}", f"_{ch}")
            F, dF = shared or self.emit_term(em, self.fresnel, "&c", "", ch)
            rho = self.slot_name("rho", ch)
            il4 = f"(real){lam ** -4!r}"
            em.line(f"const real {dr}_scale_{ch} = {ctx.c(rho)} * {il4};")
            em.add(ch, f"{dr}_scale_{ch} * {F} * {S}")
            em.add_jac(ch, rho, f"{il4} * {F} * {S}")
            for k, d in dS.items():
                em.add_jac(ch, k, f"{dr}_scale_{ch} * {F} * {d}")
            for k, d in dF.items():
                em.add_jac(ch, k, f"{dr}_scale_{ch} * {S} * {d}")
