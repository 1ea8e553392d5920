"""The float64 reference of a term, generated from its formula.

The value and derivatives of ``Term.expressions`` are turned into one numpy function per term
(SymPy's lambdify, common subexpressions shared), evaluated on the cell quantities of
``brdfcl.model.lobes.cells.Cells`` (or on the frequencies ``f`` of a PSD) in whatever precision
they come in.  This is the ground truth the OpenCL kernels are tested against.
"""
from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp

from brdfcl.model.terms.symbols import CELL, EXP_LIMIT, f

_MODULES = [{"exp_clamped": lambda x: np.exp(np.minimum(x, EXP_LIMIT))}, "scipy", "numpy"]


@cache
def compiled(term):
    """(argument names, numpy function returning (value, *derivatives)) of one term."""
    value, derivs = term.expressions()
    exprs = [value, *derivs.values()]
    free = set().union(*(e.free_symbols for e in exprs))
    args = [s for s in (f, *CELL) if s in free]
    names = [*term.inputs, *term.const_names]
    syms = [term.symbols()[n] if n in term.inputs else sp.Symbol(n, real=True) for n in names]
    fn = sp.lambdify([*args, *syms], exprs, modules=_MODULES, cse=True)
    return tuple(s.name for s in args), fn


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
