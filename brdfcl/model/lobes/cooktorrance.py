"""Cook-Torrance lobe: p = rho_s D(th) F(td) G(i, o) / (4 cos ti cos to) (docs/spec.md section 3)."""
from __future__ import annotations

from brdfcl.model.lobes.lobe import Lobe
from brdfcl.model.lobes.spec import REGISTRY, Param

RHO_S = Param("rho", 1e-6, 10.0, 0.5, log=True, per_channel=True, search=(1e-2, 5.0),
              doc="specular amplitude (times F; <= 1 for a physical surface)")


class CookTorrance(Lobe):
    prefix = "ct"
    role = "reflection"
    amplitude = RHO_S

    def __init__(self, ndf="ggx", shadowing=None, fresnel="schlick"):
        self.ndf = REGISTRY["ndf"][ndf]
        if shadowing is None:
            shadowing = f"smith_{ndf}" if f"smith_{ndf}" in REGISTRY["shadowing"] else "vcavity"
        self.shadowing = REGISTRY["shadowing"][shadowing]
        if self.shadowing.ndfs and ndf not in self.shadowing.ndfs:
            raise ValueError(f"shadowing '{shadowing}' is defined for {', '.join(self.shadowing.ndfs)} "
                             f"only, not for '{ndf}'; use vcavity or none")
        self.fresnel = REGISTRY["fresnel"][fresnel]
        self.terms = (self.ndf, self.shadowing, self.fresnel)

    def spec(self):
        g = self.shadowing.name.replace(f"_{self.ndf.name}", "").replace("_", "-")
        return f"{self.ndf.name}:{g}:{self.fresnel.name}"

    def reference(self, cells, value, consts):
        D, dD = self.ref_term(self.ndf, cells, value, consts)
        G, dG = self.ref_term(self.shadowing, cells, value, consts)
        inv = 0.25 / (cells.ci * cells.co)
        shape = D * G * inv
        dshape = {k: dD.get(k, 0.0) * G * inv + D * dG.get(k, 0.0) * inv for k in {**dD, **dG}}
        vals, jacs = [], []
        Fs = None if self.fresnel.per_channel else self.ref_term(self.fresnel, cells, value, consts)
        for ch in range(3):
            F, dF = Fs or self.ref_term(self.fresnel, cells, value, consts, ch)
            rho_name = self.slot_name("rho", ch)
            rho = value(rho_name)
            vals.append(rho * shape * F)
            jac = {rho_name: shape * F}
            jac.update({k: rho * F * d for k, d in dshape.items()})
            jac.update({k: rho * shape * d for k, d in dF.items()})
            jacs.append(jac)
        return vals, jacs

    def emit(self, em, ctx):
        D, dD = self.emit_term(em, self.ndf, "&c", "")
        G, dG = self.emit_term(em, self.shadowing, "&c", "")
        shape = f"{self.prefix}_shape"
        em.line(f"const real_v {shape} = {D} * {G} * c.inv4cico;")
        dshape = {}
        for k in {**dD, **dG}:
            parts = ([f"{dD[k]} * {G}"] if k in dD else []) + ([f"{D} * {dG[k]}"] if k in dG else [])
            dshape[k] = f"{self.prefix}_dshape_{k.split('.')[-1]}"
            em.line(f"const real_v {dshape[k]} = ({' + '.join(parts)}) * c.inv4cico;")
        shared = None if self.fresnel.per_channel else self.emit_term(em, self.fresnel, "&c", "")
        for ch in range(3):
            F, dF = shared or self.emit_term(em, self.fresnel, "&c", "", ch)
            rho = self.slot_name("rho", ch)
            em.add(ch, f"{ctx.c(rho)} * {shape} * {F}")
            em.add_jac(ch, rho, f"{shape} * {F}")
            for k, d in dshape.items():
                em.add_jac(ch, k, f"{ctx.c(rho)} * {F} * {d}")
            for k, d in dF.items():
                em.add_jac(ch, k, f"{ctx.c(rho)} * {shape} * {d}")
