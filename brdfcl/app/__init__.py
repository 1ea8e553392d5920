"""The jobs a user runs (fit-all, analyze, cluster runs) and the command line."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
