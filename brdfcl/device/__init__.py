"""OpenCL devices, programs (build, cache repair, self-test, vector width) and the engine that
uploads data and launches the kernels."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
