"""The float64 reference of a term, generated from its formula.

The value and derivatives of ``Term.expressions`` are turned into one numpy function per term
(SymPy's lambdify, common subexpressions shared), evaluated on the cell quantities of
``brdfcl.model.lobes.cells.Cells`` (or on the frequencies ``f`` of a PSD) in whatever precision
they come in.  This is the ground truth the OpenCL kernels are tested against.
"""
from __future__ import annotations

import importlib
import inspect
import json
import math
from functools import cache

import numpy as np

from brdfcl.model.terms.limits import EXP_LIMIT

_ERFC = np.frompyfunc(math.erfc, 1, 1)


def _erfc(x):
    """erfc in float64 from the C library's (math.erfc), element by element: the reference's own,
    so that a Beckmann Smith term needs no scipy import (0.1-0.2 s of every start-up)."""
    return np.asarray(_ERFC(np.asarray(x, dtype=np.float64)), dtype=np.float64)


_CUSTOM = {"exp_clamped": lambda x: np.exp(np.minimum(x, EXP_LIMIT)), "erfc": _erfc}
_MODULES = [_CUSTOM, "numpy", "scipy"]        # numpy first: its log1p, expm1 need no scipy import


@cache
def compiled(term):
    """(argument names, numpy function returning (value, *derivatives)) of one term.  The
    function's Python source is generated once per machine (brdfcl._cache.generated, keyed by the
    term's formula_key), so a process that finds it pays neither SymPy's derivatives nor lambdify."""
    from brdfcl._cache import generated
    from brdfcl.model.terms.keys import formula_key
    doc = json.loads(generated("reference", formula_key(term), lambda: _generate(term)))
    return tuple(doc["args"]), load(doc, f"reference {term.kind} {term.name}")


def _generate(term) -> str:
    """The lambdified function of a term as JSON (``portable``, with its argument names)."""
    import sympy as sp

    from brdfcl.model.terms.symbols import CELL, f
    value, derivs = term.expressions()
    exprs = [value, *derivs.values()]
    free = set().union(*(e.free_symbols for e in exprs))
    args = [s for s in (f, *CELL) if s in free]
    names = [*term.inputs, *term.const_names]
    syms = [term.symbols()[n] if n in term.inputs else sp.Symbol(n, real=True) for n in names]
    import scipy.special  # noqa: F401  (lambdify's scipy module; here: importing it costs a start-up 0.1-0.2 s)
    fn = sp.lambdify([*args, *syms], exprs, modules=_MODULES, cse=True)
    return json.dumps({"args": [s.name for s in args], **portable(fn, f"{term.kind} {term.name}")})


def portable(fn, label: str) -> dict:
    """A lambdified function as plain data: its source, its name and where each global it reads
    comes from (brdfcl's own functions, scipy.special, numpy or functools), for ``load``."""
    import functools

    import scipy.special
    where = {}
    for name in fn.__code__.co_names:
        obj = fn.__globals__.get(name)
        if name in _CUSTOM and obj is _CUSTOM[name]:
            where[name] = "brdfcl"
        elif getattr(scipy.special, name, None) is obj:
            where[name] = "scipy.special"
        elif getattr(np, name, None) is obj:
            where[name] = "numpy"
        elif getattr(functools, name, None) is obj:
            where[name] = "functools"
        else:
            raise RuntimeError(f"{label}: the generated function reads '{name}', which is not numpy's, "
                               f"scipy.special's, functools' or brdfcl's")
    return {"source": inspect.getsource(fn), "function": fn.__name__, "globals": where}


def load(doc: dict, label: str):
    """The function of a ``portable`` document, compiled in a namespace of what it reads."""
    namespace = {}
    for name, home in doc["globals"].items():
        namespace[name] = _CUSTOM[name] if home == "brdfcl" else getattr(importlib.import_module(home), name)
    exec(compile(doc["source"], f"<brdfcl {label}>", "exec"), namespace)
    return namespace[doc["function"]]


def evaluate(term, arg, **inputs):
    """(value, {input: derivative}) of ``term`` at ``arg`` (Cells, or f for a PSD), float64 numpy."""
    names, fn = compiled(term)
    if term.arg == "f":
        shape_of = np.asarray(arg)
        args = [shape_of] if names else []
    else:
        args = [getattr(arg, n) for n in names]
        shape_of = arg.ch
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = fn(*args, *(inputs[n] for n in (*term.inputs, *term.const_names)))
    dtype = np.result_type(shape_of, *(np.asarray(v) for v in inputs.values())) if inputs else shape_of.dtype
    shape = np.broadcast_shapes(np.shape(shape_of), *(np.shape(v) for v in inputs.values()))
    out = [np.broadcast_to(np.asarray(o, dtype=dtype), shape) for o in out]
    return out[0], dict(zip(term.inputs, out[1:]))
