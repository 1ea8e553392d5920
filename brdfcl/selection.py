"""Lobe comparison (docs/spec.md section 5, second test): which lobes does a material need?

Each material is fitted with the full model and with the diffraction lobe, then the
Cook-Torrance lobe, left out.  A model's penalised error is
``rmse_log * (1 + PENALTY * free parameters)``: an extra lobe is kept only if it lowers
the error by more than about PENALTY per parameter it adds (2% each, ~8% for the
diffraction lobe's four).  An information criterion (BIC) is no use here: with a
million cells any improvement of a misspecified model is "significant".
"""
from __future__ import annotations

from .model import Model

PENALTY = 0.02


def variants(spec: str) -> dict:
    """{'full': spec, 'no_diffraction': ..., 'no_ct': ...} for a model with both lobes."""
    lobes = spec.split("+")
    out = {"full": spec}
    nod = [lb for lb in lobes if not lb.startswith("diffraction")]
    noct = [lb for lb in lobes if lb.split(":")[0] in ("diffuse", "diffraction")]
    if len(nod) < len(lobes) and nod:
        out["no_diffraction"] = "+".join(nod)
    if len(noct) < len(lobes) and noct:
        out["no_ct"] = "+".join(noct)
    return out


def penalised(rmse, spec):
    return rmse * (1 + PENALTY * Model(spec).n_free)


def select(errors: dict, specs: dict):
    """The variant with the lowest penalised error: (key, {key: penalised error})."""
    pen = {k: penalised(errors[k], specs[k]) for k in errors}
    return min(pen, key=lambda k: pen[k]), pen
