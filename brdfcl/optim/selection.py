"""Lobe comparison (docs/spec.md section 5, second test): which lobes does a material need?

Each material is fitted with the full model and with the diffraction lobe, then the
Cook-Torrance lobe, left out.  A model's penalised error is
``rmse_log * (1 + PENALTY * free parameters)``: an extra lobe is kept only if it lowers
the error by more than about PENALTY per parameter it adds (2% each, ~8% for the
diffraction lobe's four).  An information criterion (BIC) is no use here: with a
million cells any improvement of a misspecified model is "significant".
"""
from __future__ import annotations

from brdfcl.model.compose import Model, parse_lobe

PENALTY = 0.02


def variants(spec: str) -> dict:
    """{'full': spec, 'no_diffraction': ..., 'no_ct': ...}: the model without its diffraction
    lobes, and without its reflection (Cook-Torrance) lobes, each where that leaves a lobe out and
    some lobe in.  Lobes are dropped by role, wherever and however often they appear."""
    lobes = spec.split("+")
    roles = [parse_lobe(t).role for t in lobes]
    out = {"full": spec}
    for key, role in (("no_diffraction", "diffraction"), ("no_ct", "reflection")):
        kept = [lb for lb, r in zip(lobes, roles) if r != role]
        if len(kept) < len(lobes) and kept:
            out[key] = "+".join(kept)
    return out


def penalised(rmse, spec):
    return rmse * (1 + PENALTY * Model(spec).n_free)


def select(errors: dict, specs: dict):
    """The variant with the lowest penalised error: (key, {key: penalised error})."""
    pen = {k: penalised(errors[k], specs[k]) for k in errors}
    return min(pen, key=lambda k: pen[k]), pen
