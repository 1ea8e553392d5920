"""The printer of the kernels' C from the terms' formulas (SymPy; imported only to make them).

``print_term(term)`` prints the value and the derivatives of ``Term.expressions`` as one C function
with shared subexpressions (SymPy's cse):

    inline real_v ndf_ggx(const cell_t *c, real alpha, real_v *d_alpha) { ... }

(a PSD takes ``real_v f`` instead of the cell).  Types follow the data: an expression that reads
the cell is a ``real_v`` (a vector of cells), one of parameters alone a ``real``.  Constants are
printed in the kernel's precision (``(real)0.5``), small integer powers as products, and a
Piecewise as ``SEL``, so the same source serves float and double, any vector width and the GLSL
export.
"""
from __future__ import annotations

import sympy as sp
from sympy.printing.c import C99CodePrinter

from brdfcl.model.terms.limits import EXP_LIMIT
from brdfcl.model.terms.symbols import BASE, CELL, DERIVED, NOTES, f

_VECTOR = frozenset((f, *CELL))


class recip(sp.Function):
    """1 / x.  Written for every negative integer power before the shared subexpressions are found,
    so that each distinct denominator is divided once (the kernels' time on a CPU is bound by the
    divide unit), and once per work-item when it depends on parameters alone (a loop invariant)."""

    nargs = 1


def _reciprocals(e):
    """``e`` with every x^-n (x not a number, n a positive integer) as recip(x)^n."""
    return e.replace(lambda x: x.is_Pow and x.exp.is_Integer and x.exp < 0 and not x.base.is_number,
                     lambda x: recip(x.base) ** (-x.exp))


def is_vector(e) -> bool:
    return bool(getattr(e, "free_symbols", set()) & _VECTOR)


class _Printer(C99CodePrinter):
    """C99 printing with OpenCL's vector rules and the kernel's ``real`` precision."""

    def __init__(self, vectors):
        super().__init__()
        self._vectors = vectors            # temporaries (cse symbols) that are vectors

    def vec(self, e) -> bool:
        return is_vector(e) or bool(getattr(e, "free_symbols", set()) & self._vectors)

    def _as_vector(self, e) -> str:
        s = self._print(e)
        return s if self.vec(e) else f"(real_v)({s})"

    def _print_Symbol(self, s):
        return f"c->{s.name}" if s in CELL else s.name

    def _print_Integer(self, e):
        return str(e.p)

    def _print_Rational(self, e):
        return f"((real){e.p}/(real){e.q})"

    def _print_Float(self, e):
        return f"(real){float(e)!r}"

    def _print_Pi(self, e):
        return "PI_R"

    def _print_recip(self, e):
        return f"((real)1 / ({self._print(e.args[0])}))"

    def _print_Exp1(self, e):
        return "(real)M_E"

    def _print_Pow(self, e):
        if e.is_number:
            return f"(real){float(e)!r}"
        b, x = e.as_base_exp()
        if isinstance(b, recip) and x.is_Integer and 0 < int(x) <= 6:     # one division, not n
            return self._print(sp.Pow(b.args[0], x, evaluate=False)).join(("((real)1 / ", ")"))
        if x.is_Integer and 0 < abs(int(x)) <= 6:
            base = self.parenthesize(b, 1000)     # an atom or a parenthesised expression
            n = abs(int(x))
            prod = base if n == 1 else "(" + " * ".join([base] * n) + ")"
            return prod if x > 0 else f"((real)1 / {prod})"
        if x == sp.Rational(1, 2):
            return f"sqrt({self._print(b)})"
        if x == sp.Rational(-1, 2):
            return f"((real)1 / sqrt({self._print(b)}))"
        if self.vec(b) or self.vec(x):
            return f"pow({self._as_vector(b)}, {self._as_vector(x)})"
        return f"pow({self._print(b)}, {self._print(x)})"

    def _minmax(self, name, args):
        args = sorted(args, key=lambda a: not self.vec(a))       # vectors first: fmin(gentype, sgentype)
        out = self._print(args[0])
        for a in args[1:]:
            out = f"{name}({out}, {self._print(a)})"
        return out

    def _print_Min(self, e):
        return self._minmax("fmin", e.args)

    def _print_Max(self, e):
        return self._minmax("fmax", e.args)

    def _print_exp_clamped(self, e):
        return f"exp({self._minmax('fmin', (e.args[0], sp.Float(EXP_LIMIT)))})"

    def _print_Piecewise(self, e):
        *pairs, (last, cond) = e.args
        assert cond == sp.true, "a Piecewise needs an otherwise branch"
        out = self._print(last)
        vector = any(self.vec(x) for x, _ in e.args)
        for value, c in reversed(pairs):
            if self.vec(c):       # select(a, b, c): b where c holds, lane by lane
                out = f"SEL({self._as_vector(last) if out == self._print(last) else out}, " \
                      f"{self._as_vector(value)}, {self._print(c)})"
            else:
                v = self._as_vector(value) if vector else self._print(value)
                out = f"(({self._print(c)}) ? {v} : {out})"
        return out


def _type(e, vectors) -> str:
    return "real_v" if is_vector(e) or bool(e.free_symbols & vectors) else "real"


def _numbers(e):
    """Irrational constants (sqrt(2), 1/sqrt(pi)) as decimals: C has no integer sqrt overload."""
    return e.replace(lambda x: x.is_number and not x.is_Atom and not x.is_Rational,
                     lambda x: sp.Float(x.evalf(20), 20))


def print_term(term) -> str:
    """The term's OpenCL function: value and derivatives, shared subexpressions, as C."""
    value, derivs = term.expressions()
    names = list(derivs)
    temps, (v, *ds) = sp.cse([_reciprocals(_numbers(e)) for e in (value, *derivs.values())],
                             symbols=sp.numbered_symbols("t"), optimizations="basic")
    vectors: set = set()
    body = []
    inline: dict = {}              # comparisons stay inside their SEL (no boolean temporaries)
    for s, e in temps:
        e = _numbers(e.xreplace(inline))
        if isinstance(e, sp.core.relational.Relational):
            inline[s] = e
            continue
        p = _Printer(vectors)
        t = _type(e, vectors)
        if t == "real_v":
            vectors.add(s)
        body.append(f"    const {t} {s} = {p._print(e)};")
    p = _Printer(vectors)
    v, ds = _numbers(v.xreplace(inline)), [_numbers(d.xreplace(inline)) for d in ds]

    def out(e):
        return p._print(e) if p.vec(e) else f"(real_v)({p._print(e)})"

    body += [f"    *d_{n} = {out(d)};" for n, d in zip(names, ds)]
    body.append(f"    return {out(v)};")
    first = "real_v f" if term.arg == "f" else "const cell_t *c"
    args = [first, *(f"real {n}" for n in (*term.inputs, *term.const_names)),
            *(f"real_v *d_{n}" for n in names)]
    head = f"/* {term.kind} {term.name}: generated from {term.origin.replace('.', '/')}.py (do not edit). */"
    return "\n".join([head, f"inline real_v {term.cfunc}({', '.join(args)})", "{", *body, "}", ""])


class _CellPrinter(_Printer):
    """Prints an expression of the stored quantities as ``make_cell``'s arguments read them."""

    def _print_Symbol(self, s):
        return s.name


def print_cells() -> str:
    """The kernels' ``cell_t`` and its prologue ``make_cell``: the stored quantities (BASE) and
    every other one printed from its expression (brdfcl.model.terms.symbols.DERIVED), in the
    order of operations written there, as the float64 reference's Cells evaluates them."""
    fields = [*BASE, *DERIVED]
    struct = [f"    real_v {s.name};{' ' * max(1, 10 - len(s.name))}/* {NOTES[s]} */" for s in fields]
    p = _CellPrinter(set())            # as written, no shared subexpressions: the compiler shares them
    body = [f"    c.{s.name} = {p._print(e) if p.vec(e) else f'(real_v)({p._print(e)})'};"
            for s, e in DERIVED.items()]
    args = ", ".join(f"real_v {s.name}" for s in BASE)
    return "\n".join(["/* The per-cell quantities: generated from brdfcl/model/terms/symbols.py (do not edit). */",
                      "typedef struct {", *struct, "} cell_t;", "",
                      f"inline cell_t make_cell({args})", "{", "    cell_t c;",
                      "    " + " ".join(f"c.{s.name} = {s.name};" for s in BASE), *body, "    return c;", "}", ""])
