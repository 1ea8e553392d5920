"""What is fitted: the terms (one formula each), the lobes (an amplitude times a product of
terms), models (a sum of lobes with its parameter vector), error metrics, and synthetic tables
made from a model."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
