"""Per-cell quantities that the lobes read, in float64: the reference of the kernels' prologue.

A cell holds the five stored quantities (``sin th, cos th, cos td, cos ti, cos to``); every other
one (``t2``, ``f0``, ``s5``, ``t2i``, ``t2o``, ``gv``, ``inv4cico``) is a property evaluated from
its expression in brdfcl.model.terms.symbols.DERIVED, the same expression the kernels'
``make_cell`` is printed from (as numpy, once per machine).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdfcl._cache import generated
from brdfcl.model.terms.keys import code_key
from brdfcl.model.terms.reference import load, portable


@dataclass
class Cells:
    sh: np.ndarray   # sin theta_h
    ch: np.ndarray   # cos theta_h
    cd: np.ndarray   # cos theta_d
    ci: np.ndarray   # cos theta_i
    co: np.ndarray   # cos theta_o

    @classmethod
    def from_geometry(cls, geom, mask=None):
        sel = slice(None) if mask is None else mask
        return cls(np.sin(geom.theta_h[sel]), np.cos(geom.theta_h[sel]), np.cos(geom.theta_d[sel]),
                   geom.cos_i[sel], geom.cos_o[sel])

    @classmethod
    def from_directions(cls, wi, wo):
        """Cells for arbitrary direction pairs (n = z), for reciprocity and integration tests."""
        h = wi + wo
        h = h / np.linalg.norm(h, axis=-1, keepdims=True)
        ch = h[..., 2]
        sh = np.sqrt(np.maximum(1.0 - ch * ch, 0.0))
        cd = np.sum(wi * h, axis=-1)
        return cls(sh, ch, cd, wi[..., 2], wo[..., 2])

    @property
    def sd(self):
        return np.sqrt(np.maximum(1.0 - self.cd ** 2, 0.0))

    def astype(self, dtype):
        return Cells(*(np.asarray(a, dtype=dtype) for a in (self.sh, self.ch, self.cd, self.ci, self.co)))

    def __len__(self):
        return self.sh.size


def _generate() -> str:
    """Each derived quantity's numpy function of the stored five, lambdified, as JSON."""
    import sympy as sp

    from brdfcl.model.terms.symbols import BASE, DERIVED, NOTES
    return json.dumps({s.name: {"doc": NOTES[s], **portable(sp.lambdify(BASE, e, "numpy"), f"cell {s.name}")}
                       for s, e in DERIVED.items()})


def _derived(name: str, doc: dict) -> property:
    f = load(doc, f"cell {name}")
    return property(lambda self: f(self.sh, self.ch, self.cd, self.ci, self.co), doc=doc["doc"])


# printed once per machine (brdfcl._cache.generated), so that making cells imports no SymPy
for _name, _doc in json.loads(generated("cells", code_key(Path(__file__)), _generate)).items():
    setattr(Cells, _name, _derived(_name, _doc))
