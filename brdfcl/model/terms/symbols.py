"""The symbols a term's formula is written in: per-cell quantities and safe special functions.

A formula (a SymPy expression) reads the cell through these symbols; it imports them (and SymPy)
where it is called, so that a run that finds the generated code made imports neither.  A cell
stores five quantities (``BASE``); the others are defined here once, as expressions of those five
(``DERIVED``): the float64 reference's ``brdfcl.model.lobes.cells.Cells`` evaluates them with
numpy and the kernels' prologue ``make_cell`` (brdfcl.kernels.terms.cell_source) is printed from
them, so that the reference and every kernel read the same quantities by the same names.
"""
from __future__ import annotations

import sympy as sp

from brdfcl.model.terms.limits import EXP_LIMIT

sh, ch, cd, ci, co = sp.symbols("sh ch cd ci co", positive=True)
"""sin theta_h, cos theta_h, cos theta_d, cos theta_i, cos theta_o."""
t2, t2i, t2o = sp.symbols("t2 t2i t2o", nonnegative=True)
"""tan^2 of theta_h, theta_i, theta_o."""
s5, gv = sp.symbols("s5 gv", nonnegative=True)
"""(1 - cos theta_d)^5 (Schlick) and the V-cavity shadowing min(1, 2 ch min(ci, co) / cd)."""
f = sp.Symbol("f", nonnegative=True)
"""Spatial frequency (1/um), the argument of a PSD."""

f0, inv4cico = sp.symbols("f0 inv4cico", positive=True)
"""2 sin theta_h cos theta_d (divided by lambda: the spatial frequency) and 1 / (4 cos ti cos to)."""

BASE = (sh, ch, cd, ci, co)
"""What a cell stores (its geometry rows on the device).  sin theta_h is stored rather than
derived so that tan^2 theta_h keeps its precision at the peak in float32."""

def _(op, *args):
    """An unevaluated operation: the order of operations as written is the float order too."""
    return op(*args, evaluate=False)


def _quotient(a, b):
    return _(sp.Mul, a, _(sp.Pow, b, -1))


def _square(a):
    return _(sp.Pow, a, 2)


_ONE_MINUS_CD = _(sp.Add, 1, _(sp.Mul, -1, cd))
DERIVED = {
    t2: _square(_quotient(sh, ch)),
    f0: _(sp.Mul, 2, sh, cd),
    s5: _(sp.Mul, _square(_square(_ONE_MINUS_CD)), _ONE_MINUS_CD),
    t2i: _quotient(_(sp.Add, 1, _(sp.Mul, -1, _square(ci))), _square(ci)),
    t2o: _quotient(_(sp.Add, 1, _(sp.Mul, -1, _square(co))), _square(co)),
    gv: sp.Min(sp.Float(1.0), _quotient(_(sp.Mul, 2, ch, sp.Min(ci, co)), cd)),
    inv4cico: _quotient(sp.Float(0.25), _(sp.Mul, ci, co)),
}
"""Every other per-cell quantity, as an expression of BASE, unevaluated: SymPy keeps it as written,
so that the kernels compute it in this order (sin theta_h / cos theta_h, squared, keeps tan^2 at
the peak as precise as float32 allows)."""

NOTES = {sh: "sin theta_h", ch: "cos theta_h", cd: "cos theta_d", ci: "cos theta_i", co: "cos theta_o",
         t2: "tan^2 theta_h", f0: "2 sin theta_h cos theta_d (times 1/lambda gives f)",
         s5: "(1 - cos theta_d)^5, Schlick", t2i: "tan^2 theta_i", t2o: "tan^2 theta_o", gv: "V-cavity G",
         inv4cico: "1 / (4 cos ti cos to)"}
"""What each per-cell quantity is."""

CELL = (sh, ch, cd, ci, co, t2, t2i, t2o, s5, gv)
"""Every per-cell symbol a term's formula may read, by the name the kernel's ``cell_t`` and
``Cells`` give it."""

class exp_clamped(sp.Function):
    """exp(min(x, EXP_LIMIT)): an exponential that cannot overflow a float.  Its derivative is
    taken as exp's (the cap is reached only where the term is ~0 anyway)."""

    nargs = 1

    def fdiff(self, argindex=1):
        return exp_clamped(self.args[0])


class expm1(sp.Function):
    """e^z - 1, exact near 0.  Printed for the kernels (and so the GLSL export, which has no expm1)
    as 2 sinh(z/2) exp(z/2), for the float64 reference as numpy's expm1; its derivative is written
    expm1(z) + 1, so that a derivative reuses the value instead of calling another function."""

    nargs = 1

    def fdiff(self, argindex=1):
        return self + 1

    def _ccode(self, printer):
        half = self.args[0] / 2
        return f"({printer._print(2 * sp.sinh(half) * sp.exp(half))})"

    def _pythoncode(self, printer):
        return f"{printer._module_format('numpy.expm1')}({printer._print(self.args[0])})"


from sympy.codegen.cfunctions import log1p  # noqa: E402  (re-exported: ln(1 + x), accurate near 0)

__all__ = ["BASE", "CELL", "DERIVED", "EXP_LIMIT", "NOTES", "cd", "ch", "ci", "co", "exp_clamped", "expm1", "f",
           "f0", "gv", "inv4cico", "log1p", "s5", "sh", "t2", "t2i", "t2o"]
