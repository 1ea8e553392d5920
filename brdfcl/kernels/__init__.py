"""OpenCL code generation: each term's function from its formula, each model's program from its
lobes, and the kernel template and shared C."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
