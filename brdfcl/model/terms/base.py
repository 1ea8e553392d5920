"""What a term is: one factor of a lobe (a D, G, F or PSD), written once as a formula.

A `Param` is one model parameter (bounds, default, log-space flag, unit).  A `Term` holds its
parameters and its formula, a SymPy expression in the cell symbols of
brdfcl.model.terms.symbols.  From the formula alone come its derivatives (SymPy), its float64
reference (brdfcl.model.terms.reference) and its OpenCL function (brdfcl.kernels.terms), so a new
term is one file that writes the formula and registers it.  All three are kept on disk once made,
so a formula imports SymPy and the cell symbols inside its function: a run that finds them made
never imports SymPy (half a second of every start-up).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from functools import cache
from typing import TYPE_CHECKING, Callable

from brdfcl.model.terms.reference import evaluate

if TYPE_CHECKING:
    import sympy as sp


@dataclass(frozen=True)
class Param:
    name: str
    lo: float
    hi: float
    default: float
    log: bool = False
    unit: str = ""
    doc: str = ""
    per_channel: bool = False     # one value per channel (amplitudes, F0, eta/k of metals)
    search: tuple | None = None   # where the global search draws candidates (default: the bounds)

    def __post_init__(self):
        assert self.lo < self.hi and self.lo <= self.default <= self.hi, self
        assert not self.log or self.lo > 0, self
        if self.search is not None:
            assert self.lo <= self.search[0] < self.search[1] <= self.hi, self

    @property
    def search_range(self):
        return self.search or (self.lo, self.hi)

    @property
    def symbol(self) -> sp.Symbol:
        import sympy as sp
        return sp.Symbol(self.name, positive=True) if self.lo > 0 else sp.Symbol(self.name, real=True)


KINDS = ("ndf", "shadowing", "fresnel", "psd")


@dataclass(frozen=True)
class Term:
    """One factor of a lobe.

    ``formula(**inputs)`` returns the term's value as a SymPy expression of the cell symbols
    (or of ``f``, the spatial frequency, for a PSD), given one symbol per input (its parameters,
    then the ``uses`` it reads from another term) and, for each name in ``host``, a function of
    its inputs computed on the host (a normalisation constant, a series' coefficients):
    ``host_consts(**inputs)`` returns ``({name: value}, {name: {input: derivative}})`` in float64."""

    kind: str                       # one of KINDS
    name: str
    params: tuple[Param, ...]
    formula: Callable[..., sp.Expr]
    cite: str = ""
    doc: str = ""
    uses: tuple[str, ...] = ()      # parameters read from another term (G reads D's alpha)
    ndfs: tuple[str, ...] = ()      # shadowing: the D terms it is defined for (empty: any)
    family: str = ""                # shadowing: the word a model string names it by (smith, smith-hc, ...)
    sampled_as: str = ""            # ndf: the half-vector distribution that samples it exactly from its alpha
    #                                 (ggx, beckmann; empty: a proposal fitted to its shape)
    per_channel: bool = False       # evaluated once per channel (per-channel parameters)
    host: tuple[str, ...] = ()      # constants of the inputs alone, computed on the host
    host_consts: Callable | None = None
    origin: str = ""                # the module that registered it (set by ``register``)

    def __post_init__(self):
        assert self.kind in KINDS, self.kind
        assert bool(self.host) == (self.host_consts is not None), self.name

    @property
    def arg(self) -> str:
        """What the term reads: ``f`` (a PSD, of the spatial frequency) or ``cell``."""
        return "f" if self.kind == "psd" else "cell"

    @property
    def cfunc(self) -> str:
        """The name of its OpenCL function."""
        return f"{self.kind}_{self.name}"

    @property
    def inputs(self) -> tuple[str, ...]:
        """Parameter names the term takes, in argument order."""
        return tuple(p.name for p in self.params) + self.uses

    @property
    def const_names(self) -> tuple[str, ...]:
        """Host constants passed to the kernel: each constant, then its derivative by each
        input (``N, dN_alpha, dN_p``)."""
        return tuple(n for k in self.host for n in (k, *(f"d{k}_{p}" for p in self.inputs)))

    def consts(self, **inputs) -> dict:
        """The host constants of ``const_names`` at these input values."""
        if self.host_consts is None:
            return {}
        k, d = self.host_consts(**inputs)
        return {n: v for name in self.host
                for n, v in ((name, k[name]), *((f"d{name}_{p}", g) for p, g in d[name].items()))}

    def symbols(self) -> dict[str, sp.Symbol]:
        """The input symbols, by name (a ``uses`` input is a positive real)."""
        import sympy as sp
        out = {p.name: p.symbol for p in self.params}
        out.update({u: sp.Symbol(u, positive=True) for u in self.uses})
        return out

    def expressions(self) -> tuple[sp.Expr, dict[str, sp.Expr]]:
        """The value and its derivative by each input, in plain symbols (host constants and their
        derivatives as the symbols of ``const_names``)."""
        return _expressions(self)

    def reference(self, arg, **inputs):
        """float64 value and {input: derivative} at ``arg`` (Cells, or f for a PSD); the host
        constants are computed from the inputs where they are not given."""
        if self.host and not set(self.const_names) <= set(inputs):
            inputs = {**inputs, **self.consts(**{n: inputs[n] for n in self.inputs})}
        return evaluate(self, arg, **inputs)


@cache
def _expressions(term: Term):
    import sympy as sp
    syms = term.symbols()
    inputs = [syms[n] for n in term.inputs]
    funcs = {k: sp.Function(k)(*inputs) for k in term.host}
    value = sp.sympify(term.formula(**syms, **funcs))
    plain = {fn: sp.Symbol(k, real=True) for k, fn in funcs.items()}
    derivs = {}
    for name, s in syms.items():
        d = sp.diff(value, s)
        for k, fn in funcs.items():
            for n, x in zip(term.inputs, inputs):
                d = d.subs(sp.Derivative(fn, x), sp.Symbol(f"d{k}_{n}", real=True))
        derivs[name] = d.subs(plain)
        assert not derivs[name].atoms(sp.Derivative), (term.name, name)
    return value.subs(plain), derivs


REGISTRY: dict[str, dict[str, Term]] = {k: {} for k in KINDS}


def register(term: Term) -> Term:
    """Make a term available to model strings, the catalogue and the tests."""
    term = replace(term, origin=term.origin or sys._getframe(1).f_globals["__name__"])
    assert term.kind != "shadowing" or term.family, f"shadowing {term.name}: give its family"
    REGISTRY[term.kind][term.name] = term
    return term


def shadowing_families() -> list[str]:
    """The words a model string names a shadowing by: those of terms made for particular D terms
    first (``smith``, ``smith-hc``), then those for any D (``none``, ``vcavity``)."""
    terms = REGISTRY["shadowing"].values()
    per_d = [t.family for t in terms if t.ndfs]
    return list(dict.fromkeys(per_d + [t.family for t in terms if t.family not in per_d]))


def shadowing_for(ndf: str, family: str) -> Term | None:
    """The shadowing term of ``family`` for the D ``ndf``: one defined for it (``ndfs``), else one
    defined for any D; None if the family has none for it."""
    terms = [t for t in REGISTRY["shadowing"].values() if t.family == family]
    return next((t for t in terms if ndf in t.ndfs), next((t for t in terms if not t.ndfs), None))
