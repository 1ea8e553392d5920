"""The lobes a model sums: each an amplitude per channel times a product of terms."""
from brdfcl.model.lobes.cooktorrance import CookTorrance
from brdfcl.model.lobes.diffraction import Diffraction
from brdfcl.model.lobes.diffuse import Diffuse
from brdfcl.model.lobes.lobe import LAMBDAS, ROLES, Lobe
from brdfcl.model.terms import REGISTRY, Param, Term

__all__ = ["CookTorrance", "Diffraction", "Diffuse", "LAMBDAS", "REGISTRY", "ROLES", "Lobe", "Param", "Term"]
