"""Read a fitted model from a ``NAME.json`` result (or the same document as a dict).

``fit-all`` writes the model spec under ``"model"``, every parameter under ``"params"`` as
``{name: {"value": v, "lo": ..., "hi": ..., ...}}`` and the channel wavelengths under
``"wavelengths_um"``.  A plain ``{name: value}`` mapping of parameters (the shape of the demo
database's ``truth.json`` entries) is accepted too.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass

import numpy as np

from brdfcl.model.compose import Model


@dataclass
class Fit:
    """A fitted model: the model, its natural parameter vector (model.names order), the source."""

    model: Model
    values: np.ndarray
    name: str
    doc: dict

    def as_dict(self):
        return self.model.as_dict(self.values)


def _read_doc(src) -> tuple[dict, str]:
    if isinstance(src, dict):
        return src, str(src.get("material", "brdfcl"))
    path = os.fspath(src)
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except OSError as e:
        raise OSError(f"cannot read fit result {path}: {e.strerror or e}") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not a brdfcl fit result (invalid JSON: {e})") from None
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: not a brdfcl fit result (expected a JSON object)")
    stem = os.path.splitext(os.path.basename(path))[0]
    return doc, str(doc.get("material", stem))


def load_fit(src) -> Fit:
    """A `Fit` from a path to ``NAME.json`` or its parsed document.

    Raises ValueError naming what is missing when the document is not a fit result."""
    doc, name = _read_doc(src)
    where = name if isinstance(src, dict) else os.fspath(src)
    if "model" not in doc or "params" not in doc or not isinstance(doc["params"], dict):
        raise ValueError(f"{where}: not a brdfcl fit result (needs 'model' and 'params')")
    lambdas = doc.get("wavelengths_um")
    model = Model(doc["model"], lambdas=tuple(lambdas)) if lambdas else Model(doc["model"])
    params = doc["params"]
    missing = [n for n in model.names if n not in params]
    if missing:
        raise ValueError(f"{where}: parameters missing for {model.spec}: {', '.join(missing)}")
    vals = []
    for n in model.names:
        p = params[n]
        v = p.get("value") if isinstance(p, dict) else p
        try:
            v = float(v)  # type: ignore[arg-type]  # None and text are caught below
        except (TypeError, ValueError):
            raise ValueError(f"{where}: parameter {n} has no numeric value ({p!r})") from None
        if not np.isfinite(v):
            raise ValueError(f"{where}: parameter {n} is not finite ({v})")
        vals.append(v)
    return Fit(model, np.array(vals), name, doc)


def fit_document(model: Model, values, material: str = "brdfcl") -> dict:
    """A minimal fit document (the shape of ``NAME.json``) for known parameters."""
    values = np.asarray(values, dtype=np.float64)
    return {"material": material, "model": model.spec, "wavelengths_um": list(model.lambdas),
            "params": {s.name: {"value": float(v), "lo": float(s.param.lo), "hi": float(s.param.hi),
                                "log_space": bool(s.param.log), "unit": s.param.unit,
                                "fixed": s.name in model.fixed}
                       for s, v in zip(model.slots, values)}}
