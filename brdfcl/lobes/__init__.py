"""Lobe and term descriptions with their float64 references (docs/spec.md section 3)."""
from . import fresnel, ndf, psd, shadowing  # noqa: F401  (register the terms)
from .cooktorrance import CookTorrance
from .diffraction import LAMBDAS, Diffraction
from .diffuse import Diffuse
from .spec import REGISTRY, Param, Term

__all__ = ["CookTorrance", "Diffraction", "Diffuse", "LAMBDAS", "REGISTRY", "Param", "Term"]
