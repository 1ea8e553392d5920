"""Fitting.  The pipeline is `fit` (Fitter.fit); its stages are plain functions returning a
`result.StageResult`: `search` (global search, start picking), `refine` (Levenberg-Marquardt of
`lm`, reviving dead lobes), `assessment` (errors, standard errors of `uncertainty`, albedo of
`albedo`, flags).  `objective` holds the loss with every penalty (`peak_order`), `spaces` the
parameter spaces, `options` FitOptions, `lockstep` batched nlopt, `selection` lobe selection."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
