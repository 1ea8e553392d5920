"""The symbols a term's formula is written in: per-cell quantities and safe special functions.

A formula (a SymPy expression) reads the cell through these symbols; the float64 reference
(brdfcl.model.terms.reference) takes them from ``brdfcl.model.lobes.cells.Cells`` and the OpenCL
code (brdfcl.kernels.terms) from the kernel's ``cell_t`` of the same names (kernels/common.cl).
"""
from __future__ import annotations

import sympy as sp

sh, ch, cd, ci, co = sp.symbols("sh ch cd ci co", positive=True)
"""sin theta_h, cos theta_h, cos theta_d, cos theta_i, cos theta_o."""
t2, t2i, t2o = sp.symbols("t2 t2i t2o", nonnegative=True)
"""tan^2 of theta_h, theta_i, theta_o."""
s5, gv = sp.symbols("s5 gv", nonnegative=True)
"""(1 - cos theta_d)^5 (Schlick) and the V-cavity shadowing min(1, 2 ch min(ci, co) / cd)."""
f = sp.Symbol("f", nonnegative=True)
"""Spatial frequency (1/um), the argument of a PSD."""

CELL = (sh, ch, cd, ci, co, t2, t2i, t2o, s5, gv)
"""Every per-cell symbol, by the name the kernel's ``cell_t`` and ``Cells`` give it."""

EXP_LIMIT = 40.0
"""exp_clamped's cap on its argument.  exp(-e^40) is 0 in float and double alike, so capping the
inner exponent of exp(-exp(x)) never changes a value, and e^40 ~ 2.4e17 times the normalisation
of a sharp lobe (~1e8) still fits a float, where e^80 overflowed into inf * 0 = NaN."""


class exp_clamped(sp.Function):
    """exp(min(x, EXP_LIMIT)): an exponential that cannot overflow a float.  Its derivative is
    taken as exp's (the cap is reached only where the term is ~0 anyway)."""

    nargs = 1

    def fdiff(self, argindex=1):
        return exp_clamped(self.args[0])


from sympy.codegen.cfunctions import log1p  # noqa: E402  (re-exported: ln(1 + x), accurate near 0)

__all__ = ["CELL", "EXP_LIMIT", "cd", "ch", "ci", "co", "exp_clamped", "f", "gv", "log1p", "s5", "sh",
           "t2", "t2i", "t2o"]
