"""Measurements as they are stored: MERL tables and their geometry, scattered spectral samples,
the readers of each format, and the checks that keep input files read-only."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
