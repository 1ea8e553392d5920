"""Which physical effect makes which part of a measured BRDF: the gradient test, the wavelength
check and the lobe comparison, per material."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
