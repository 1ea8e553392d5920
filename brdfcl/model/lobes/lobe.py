"""What a lobe is: an amplitude per channel times a product of factors.

Each lobe kind (diffuse.py, cooktorrance.py, diffraction.py) says only which factors make it:
``parts(ch)`` gives, for one channel, a parameter-free scale (a `Known`) and the terms it
multiplies (`Factor`s).  The product rule, its float64 reference and the OpenCL C that computes
the same are written once, here, for every lobe: factors that do not depend on the channel are
evaluated once and shared, the rest once per channel.

One module (~250 lines) because the float64 product rule and the OpenCL one must be read side
by side: they are the two halves of one formula.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from brdfcl.model.terms import Param, Term

RGB_NAMES = ("r", "g", "b")
LAMBDAS = (0.645, 0.526, 0.444)
"""Default wavelengths (um) of the R, G, B channels."""

ROLES = ("diffuse", "diffraction", "reflection")
"""What a lobe stands for.  Analysis, lobe selection and the peak constraint ask for lobes by
role (``Model.lobes_with_role``), never by name or kind."""


def channel_names(lambdas) -> tuple[str, ...]:
    """Names of the channels in parameter names: r, g, b for three, else the wavelength in nm."""
    lambdas = tuple(float(x) for x in lambdas)
    if len(lambdas) == 3:
        return RGB_NAMES
    names = tuple(f"{x * 1000:g}nm".replace(".", "p") for x in lambdas)
    if len(set(names)) != len(names):
        raise ValueError(f"channel wavelengths {lambdas} um: two channels share a wavelength")
    return names


@dataclass(frozen=True)
class Slot:
    """One scalar of the model's parameter vector."""

    name: str                  # full name, e.g. "ct.F0_g"
    param: Param
    channel: int | None        # channel of a per-channel parameter
    lobe: str
    amplitude: bool = False    # the lobe's amplitude: the model is linear in it

    @property
    def cname(self):
        return c_name(self.name)


def c_name(slot_name: str) -> str:
    """The C constant that holds a parameter in the kernels (``P_ct_alpha``)."""
    return "P_" + slot_name.replace(".", "_")


@dataclass(frozen=True)
class Known:
    """A parameter-free quantity of the cell, written in both languages: a lobe's scale or the
    argument of a term (a PSD's frequency)."""

    c: str                                 # C, over the kernel's cell ``c`` (``c.inv4cico``)
    ref: Callable                          # Cells -> float64 numpy (or a number)


@dataclass(frozen=True)
class Factor:
    """One term of a lobe's product, at its argument (None: the cell)."""

    term: Term
    arg: Known | None = None
    channel: int | None = None             # the channel it depends on (None: shared by all)


class Emitter:
    """Collects the C lines and the per-channel value and Jacobian expressions of a model."""

    def __init__(self, index_of, n_channels=3):
        self.lines: list[str] = []
        self.value: list[list[str]] = [[] for _ in range(n_channels)]
        self.jac: list[dict[int, list[str]]] = [{} for _ in range(n_channels)]
        self._index_of = index_of        # slot name -> column (None when fixed)

    def line(self, s):
        self.lines.append(s)

    def add(self, ch, expr):
        self.value[ch].append(expr)

    def add_jac(self, ch, slot_name, expr):
        col = self._index_of(slot_name)
        if col is not None:
            self.jac[ch].setdefault(col, []).append(expr)


class Lobe:
    """Base for the lobes.  ``prefix`` names its parameters (``ct.alpha``); ``role`` is one of
    ROLES.  The class's ``prefix`` is its kind's; a model holding a kind more than once gives
    the second ``ct2``, the third ``ct3``, ... (``Model`` sets the instance's ``prefix``)."""

    prefix: str
    role: str
    amplitude: Param
    terms: tuple[Term, ...] = ()
    lambdas: tuple[float, ...] = LAMBDAS

    @property
    def kind(self) -> str:
        """The kind's prefix (``ct`` for every Cook-Torrance lobe, also for one named ``ct2``)."""
        return type(self).prefix

    @property
    def channels(self) -> tuple[str, ...]:
        return channel_names(self.lambdas)

    def spec(self) -> str:
        """The lobe's part of a model string (``ggx:smith:schlick``)."""
        raise NotImplementedError

    def parts(self, ch: int) -> tuple[Known | None, list[Factor]]:
        """Channel ``ch``'s scale and factors: value = amplitude_ch * scale * prod(factors)."""
        raise NotImplementedError

    # --- parameters --------------------------------------------------------------------------
    def slots(self) -> list[Slot]:
        names = self.channels
        out = [Slot(f"{self.prefix}.{self.amplitude.name}_{n}", self.amplitude, c, self.prefix, True)
               for c, n in enumerate(names)]
        for t in self.terms:
            for p in t.params:
                if p.per_channel:
                    out += [Slot(f"{self.prefix}.{p.name}_{n}", p, c, self.prefix) for c, n in enumerate(names)]
                else:
                    out.append(Slot(f"{self.prefix}.{p.name}", p, None, self.prefix))
        return out

    def slot_name(self, pname, ch=None, term=None):
        per = any(p.name == pname and p.per_channel
                  for t in ((term,) if term else self.terms) if t for p in t.params)
        per = per or pname == self.amplitude.name
        return f"{self.prefix}.{pname}_{self.channels[ch]}" if per else f"{self.prefix}.{pname}"

    def const_names(self):
        return [f"{self.prefix}.{t.kind}.{k}" for t in self.terms for k in t.const_names]

    def consts(self, value):
        """Host constants of this lobe's terms: {full const name: value}."""
        out = {}
        for t in self.terms:
            if not t.host:
                continue
            kw = {p: value(n) for p, n in self._inputs(t, None).items()}
            for k, v in t.consts(**kw).items():
                out[f"{self.prefix}.{t.kind}.{k}"] = v
        return out

    def _inputs(self, term, ch):
        """{term input: slot name}: a per-channel term reads its channel's parameters."""
        return {p: self.slot_name(p, ch if term.per_channel else None, term) for p in term.inputs}

    # --- the product rule, float64 -------------------------------------------------------------
    def ref_term(self, term, arg, value, consts, ch=None):
        """(value, {slot name: derivative}) of one of this lobe's terms at ``arg``, float64."""
        names = self._inputs(term, ch)
        kw = {p: value(n) for p, n in names.items()}
        kw.update({k: consts[f"{self.prefix}.{term.kind}.{k}"] for k in term.const_names})
        v, d = term.reference(arg, **kw)
        return v, {names[p]: g for p, g in d.items()}

    def reference(self, cells, value, consts):
        """float64 value and Jacobian per channel: ([value], [{slot name: derivative}])."""
        done: dict = {}
        vals, jacs = [], []
        for ch in range(len(self.lambdas)):
            scale, factors = self.parts(ch)
            evaluated = []
            for fac in factors:
                key = (fac.term.name, fac.channel)
                if key not in done:
                    arg = cells if fac.arg is None else fac.arg.ref(cells)
                    done[key] = self.ref_term(fac.term, arg, value, consts, fac.channel)
                evaluated.append(done[key])
            k = 1.0 if scale is None else scale.ref(cells)
            amp = self.slot_name(self.amplitude.name, ch)
            rest = [k * np.prod([v for j, (v, _) in enumerate(evaluated) if j != i], axis=0)
                    for i in range(len(evaluated))]
            shape = k * np.prod([v for v, _ in evaluated], axis=0) if evaluated else k
            shape = np.broadcast_to(shape, (len(cells),))
            a = value(amp)
            jac = {amp: shape}
            for (_, d), r in zip(evaluated, rest):
                for name, g in d.items():
                    jac[name] = jac.get(name, 0.0) + a * r * g
            vals.append(a * shape)
            jacs.append(jac)
        return vals, jacs

    # --- the product rule, OpenCL C -------------------------------------------------------------
    def emit(self, em: Emitter) -> None:
        """The OpenCL C that computes what ``reference`` does."""
        pre = self.prefix
        parts = [self.parts(ch) for ch in range(len(self.lambdas))]
        shared_scale = len({s.c if s else None for s, _ in parts}) == 1
        shared = [f for f in parts[0][1] if f.channel is None]
        # the channel-independent part: S = scale * prod(shared factors), and dS
        calls = [self._emit_term(em, f) for f in shared]
        base = [parts[0][0].c] if shared_scale and parts[0][0] else []
        S = None
        dS: dict[str, str] = {}
        if calls or base:
            S = f"{pre}_shape"
            em.line(f"const real_v {S} = {' * '.join([v for v, _ in calls] + base)};")
            sums: dict[str, list[str]] = {}
            for i, (_, d) in enumerate(calls):
                others = [v for j, (v, _) in enumerate(calls) if j != i] + base
                for name, dv in d.items():
                    sums.setdefault(name, []).append(" * ".join([dv] + others))
            for name, terms in sums.items():
                dS[name] = f"{pre}_dshape_{name.split('.', 1)[1]}"
                em.line(f"const real_v {dS[name]} = {' + '.join(terms)};")
        for ch, (scale, factors) in enumerate(parts):
            own = [self._emit_term(em, f) for f in factors if f.channel is not None]
            amp = c_name(self.slot_name(self.amplitude.name, ch))
            k = [] if shared_scale or scale is None else [f"({scale.c})"]
            if k:
                em.line(f"const real {pre}_scale_{ch} = {amp} * {k[0]};")
                a = f"{pre}_scale_{ch}"
            else:
                a = amp
            rest = ([S] if S else []) + [v for v, _ in own]
            em.add(ch, " * ".join([a] + rest))
            em.add_jac(ch, self.slot_name(self.amplitude.name, ch), " * ".join(k + rest) or "(real_v)1")
            for name, dn in dS.items():
                em.add_jac(ch, name, " * ".join([a, dn] + [v for v, _ in own]))
            for i, (_, d) in enumerate(own):
                others = ([S] if S else []) + [v for j, (v, _) in enumerate(own) if j != i]
                for name, dv in d.items():
                    em.add_jac(ch, name, " * ".join([a] + others + [dv]))

    def _emit_term(self, em, fac: Factor):
        """Emit one factor's call; returns (C value name, {slot name: C derivative name})."""
        term = fac.term
        tag = "" if fac.channel is None else f"_{fac.channel}"
        base = f"{self.prefix}_{term.kind}{tag}"
        names = self._inputs(term, fac.channel)
        ins = [c_name(names[p]) for p in term.inputs]
        ins += ["K_" + f"{self.prefix}.{term.kind}.{k}".replace(".", "_") for k in term.const_names]
        outs = {names[p]: f"{base}_d{p}" for p in term.inputs}
        if outs:
            em.line(f"real_v {', '.join(outs.values())};")
        arg = "&c" if fac.arg is None else f"({fac.arg.c})"
        em.line(f"const real_v {base} = {term.cfunc}({', '.join([arg, *ins, *(f'&{d}' for d in outs.values())])});")
        return base, outs
