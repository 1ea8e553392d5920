"""The PSD of the talk (Holzschuch & Pacanowski, Identifying diffraction effects in measured BRDFs):
S(f) = 1 / (1 + f^2/a^2)^2, a Fourier spectrum ~ 1/(1 + w^2) of a C0 surface, S(0) = 1."""
from brdfcl.model.terms.base import Param, Term, register

A = Param("a", 0.1, 1e2, 1.0, log=True, unit="1/um", search=(0.1, 20.0),
          doc="PSD corner frequency (width of the diffraction lobe); the lower bound keeps the lobe "
              "off the specular peak (half width >= ~1.5 deg at 0.526 um), the talk's separation")


def hp(a):
    from brdfcl.model.terms.symbols import f
    return 1 / (1 + (f / a) ** 2) ** 2


register(Term("psd", "hp", (A,), hp, doc="1 / (1 + f^2/a^2)^2: Fourier spectrum ~ 1/(1 + w^2), a C0 surface",
              cite="Holzschuch & Pacanowski, Identifying diffraction effects in measured BRDFs"))
