"""Each term's OpenCL function and the kernels' cell prologue, generated from the formulas
(brdfcl.model.terms) by brdfcl.kernels.printer, once per machine: kept in brdfcl's cache
(brdfcl._cache.generated) under a key of the code they are printed from, so that a process that
finds them imports no SymPy.
"""
from __future__ import annotations

import hashlib
from functools import cache
from pathlib import Path

from brdfcl._cache import generated
from brdfcl.model.terms.keys import code_key, formula_key

_PRINTER = Path(__file__).with_name("printer.py")


@cache
def c_source(term) -> str:
    """The term's OpenCL function (value returned, derivatives through pointers):

        inline real_v ndf_ggx(const cell_t *c, real alpha, real_v *d_alpha) { ... }

    (a PSD takes ``real_v f`` instead of the cell), keyed by the term's formula_key and the printer."""
    return generated("c", _source_key(term), lambda: _print_c(term))


def _source_key(term) -> str:
    return hashlib.sha1((formula_key(term) + _PRINTER.read_text() + Path(__file__).read_text()).encode()
                        ).hexdigest()[:24]


def _print_c(term) -> str:
    from brdfcl.kernels.printer import print_term
    return print_term(term)


@cache
def cell_source() -> str:
    """The kernels' ``cell_t`` and its prologue ``make_cell`` (brdfcl.kernels.printer.print_cells)."""
    def make():
        from brdfcl.kernels.printer import print_cells
        return print_cells()
    return generated("c", "cells-" + code_key(_PRINTER, Path(__file__)), make)
