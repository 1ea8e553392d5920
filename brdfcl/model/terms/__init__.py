"""Every D, G, F and PSD term, one file each, written once as a formula (brdfcl.model.terms.base)."""
from brdfcl.model.terms import fresnel, ndf, psd, shadowing  # noqa: F401  (importing them registers the terms)
from brdfcl.model.terms.base import KINDS, REGISTRY, Param, Term, register, shadowing_families, shadowing_for

__all__ = ["KINDS", "REGISTRY", "Param", "Term", "register", "shadowing_families", "shadowing_for"]
