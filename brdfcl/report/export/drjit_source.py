"""A term's formula printed as Dr.Jit Python: the value a Mitsuba 3 BSDF evaluates on a wavefront.

The same SymPy expression the OpenCL kernels and the float64 reference are generated from
(``Term.expressions``) is printed as one Python function per term, common subexpressions shared,
whose arithmetic is Dr.Jit's: it runs on ``mi.Float`` arrays in the JIT variants (``llvm_ad_rgb``,
``cuda_ad_rgb``; traced once per kernel, differentiable by Dr.Jit's AD) and on Python floats in
the scalar ones.  Only the value is printed; derivatives come from Dr.Jit's AD.

What the printer maps (Dr.Jit 1.x has neither ``erfc`` nor ``log1p``):

* ``Piecewise`` -> nested ``dr.select`` (both branches are evaluated, as in the kernels' ``SEL``);
  ``Min`` / ``Max`` -> ``dr.minimum`` / ``dr.maximum``;
* ``x**2`` ... -> products, ``x**(1/2)`` -> ``dr.sqrt``, ``x**(-1/2)`` -> ``dr.rsqrt``,
  ``x**(-n)`` -> ``1 / ...``, other powers -> ``dr.power``;
* ``exp``, ``log``, ``sqrt`` -> Dr.Jit's; ``log1p`` -> ``_log1p`` and ``erfc`` -> ``_erfc``
  (brdfcl.report.export.special, as in the GLSL export); ``exp_clamped`` -> ``_exp_clamped``
  (exp of min(x, EXP_LIMIT)).

Per-cell quantities other than the five stored ones are printed from their definitions
(brdfcl.model.terms.symbols.DERIVED) by ``cell_source``.  Both texts are kept in brdfcl's cache
(brdfcl._cache.generated), keyed by the formula and by this printer's source.
"""
from __future__ import annotations

import hashlib
from functools import cache
from pathlib import Path

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from brdfcl.model.terms.symbols import BASE, CELL, DERIVED, EXP_LIMIT, f
from brdfcl.report.export.special import erfcc_exponent

HELPERS = f'''\
def _log1p(x):
    u = 1.0 + x
    return dr.select(u == 1.0, x, dr.log(u) * (x / (u - 1.0)))


def _exp_clamped(x):
    return dr.exp(dr.minimum(x, {EXP_LIMIT!r}))


def _erfc(x):
    z = dr.abs(x)
    t = 1.0 / (1.0 + 0.5 * z)
    r = t * dr.exp({erfcc_exponent()})
    return dr.select(x >= 0.0, r, 2.0 - r)
'''
"""Functions the printed terms call that Dr.Jit does not have."""

_FUNCS = {"exp": "dr.exp", "log": "dr.log", "log1p": "_log1p", "exp_clamped": "_exp_clamped", "erfc": "_erfc",
          "Abs": "dr.abs"}


class DrJitPrinter(PythonCodePrinter):
    """SymPy -> Python over Dr.Jit arrays (``import drjit as dr`` in the namespace).  A function
    class's own ``_pythoncode`` is not used: every function goes through ``_print_Function``, which
    refuses one it has no Dr.Jit counterpart for."""

    printmethod = "_drjitcode"

    def _print(self, expr, **kwargs):
        if isinstance(expr, sp.Function) and not isinstance(expr, (sp.Piecewise, sp.Min, sp.Max)):
            return self._print_Function(expr)
        return super()._print(expr, **kwargs)

    def _print_Function(self, expr):
        name = type(expr).__name__
        if name not in _FUNCS:
            raise ValueError(f"the Dr.Jit printer has no function for {name}")
        return f"{_FUNCS[name]}({', '.join(self._print(a) for a in expr.args)})"

    def _print_Piecewise(self, expr):
        *pairs, (last, cond) = expr.args
        if cond is not sp.true:
            raise ValueError("a Piecewise without an otherwise branch cannot be printed as dr.select")
        out = self._print(last)
        for value, c in reversed(pairs):
            out = f"dr.select({self._print(c)}, {self._print(value)}, {out})"
        return out

    def _print_Relational(self, expr):
        return f"({self._print(expr.lhs)} {expr.rel_op} {self._print(expr.rhs)})"

    def _print_And(self, expr):
        return "(" + " & ".join(self._print(a) for a in expr.args) + ")"

    def _print_Or(self, expr):
        return "(" + " | ".join(self._print(a) for a in expr.args) + ")"

    def _print_Not(self, expr):
        return f"(~{self._print(expr.args[0])})"

    def _minmax(self, expr, fn):
        *rest, last = expr.args
        out = self._print(last)
        for a in reversed(rest):
            out = f"{fn}({self._print(a)}, {out})"
        return out

    def _print_Min(self, expr):
        return self._minmax(expr, "dr.minimum")

    def _print_Max(self, expr):
        return self._minmax(expr, "dr.maximum")

    def _print_Pow(self, expr, rational=False):
        b, e = expr.args
        base = self.parenthesize(b, 100)          # always parenthesised where it is compound
        if e == sp.Rational(1, 2):
            return f"dr.sqrt({self._print(b)})"
        if e == sp.Rational(-1, 2):
            return f"dr.rsqrt({self._print(b)})"
        if e.is_Integer and 0 < int(e) <= 8:
            return "(" + " * ".join([base] * int(e)) + ")"
        if e.is_Integer and -8 <= int(e) < 0:
            return "(1.0 / (" + " * ".join([base] * -int(e)) + "))"
        return f"dr.power({self._print(b)}, {self._print(e)})"

    def _print_Rational(self, expr):
        return repr(float(expr))

    def _print_Half(self, expr):
        return "0.5"

    def _print_Integer(self, expr):
        return repr(float(expr))

    def _print_Float(self, expr):
        return repr(float(expr))

    def _print_Pi(self, expr):
        return repr(float(sp.pi))

    def _print_Exp1(self, expr):
        return repr(float(sp.E))

    def _print_BooleanTrue(self, expr):
        return "True"

    def _print_BooleanFalse(self, expr):
        return "False"


def _function(name: str, args: list[str], exprs: list[sp.Expr], returns: str) -> str:
    """``def name(args): ...`` computing ``exprs`` with common subexpressions shared; ``returns``
    formats the printed results into the return statement."""
    p = DrJitPrinter({"fully_qualified_modules": False})
    subs, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("_x"), optimizations="basic")
    lines = [f"def {name}({', '.join(args)}):"]
    lines += [f"    {s} = {p.doprint(e)}" for s, e in subs]
    lines.append("    return " + returns.format(*(p.doprint(e) for e in reduced)))
    return "\n".join(lines) + "\n"


@cache
def _printer_hash() -> str:
    return hashlib.sha1(Path(__file__).read_bytes() + sp.__version__.encode()).hexdigest()[:16]


def term_args(term) -> tuple[str, ...]:
    """What the printed function of ``term`` takes, in order: the cell quantities it reads (or
    ``f``, a PSD's frequency), its inputs, then its host constants."""
    return tuple(_term(term)[0])


def term_source(term) -> str:
    """The Dr.Jit function ``value(...)`` of one term (its arguments: `term_args`)."""
    return _term(term)[1]


@cache
def _term(term) -> tuple[list[str], str]:
    import json

    from brdfcl._cache import generated
    from brdfcl.model.terms.keys import formula_key

    def make():
        value, _ = term.expressions()
        free = value.free_symbols
        cell = [s.name for s in (f, *CELL) if s in free]
        if term.arg == "f":
            cell = ["f"]
        args = [*cell, *term.inputs, *term.const_names]
        return json.dumps({"args": args, "source": _function("value", args, [value], "{}")})
    doc = json.loads(generated("drjit", f"{formula_key(term)}-{_printer_hash()}", make))
    return doc["args"], doc["source"]


def cell_source() -> str:
    """``derived(sh, ch, cd, ci, co)``: every DERIVED quantity, as a dict by name, from the five
    stored ones."""
    from brdfcl._cache import generated
    from brdfcl.model.terms.keys import _terms_files_hash

    def make():
        body = "{{" + ", ".join(f"{s.name!r}: {{}}" for s in DERIVED) + "}}"
        return _function("derived", [s.name for s in BASE], list(DERIVED.values()), body)
    return generated("drjit", f"cells-{_printer_hash()}-{_terms_files_hash()[:16]}", make)
