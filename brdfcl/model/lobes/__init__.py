"""Lobe and term descriptions with their float64 references (docs/spec.md section 3)."""
from brdfcl.model.lobes import fresnel, ndf, psd, shadowing  # noqa: F401  (register the terms)
from brdfcl.model.lobes.cooktorrance import CookTorrance
from brdfcl.model.lobes.diffraction import LAMBDAS, Diffraction
from brdfcl.model.lobes.diffuse import Diffuse
from brdfcl.model.lobes.spec import REGISTRY, Param, Term

__all__ = ["CookTorrance", "Diffraction", "Diffuse", "LAMBDAS", "REGISTRY", "Param", "Term"]
