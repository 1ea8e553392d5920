"""Fitting: the objective with its penalties, the global search, Levenberg-Marquardt, the
lockstep driver, lobe selection and the uncertainty of a fit."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
