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
    argument of a term (a PSD's frequency).  ``k`` is a number of the channel (1 / lambda) that
    the C names ``{k}``: a literal where each channel has its own code, an entry of a table where
    one loop serves every channel."""

    c: str                                 # C, over the kernel's cell ``c`` (``c.inv4cico``)
    ref: Callable                          # Cells -> float64 numpy (or a number)
    k: float | None = None

    def code(self, k: str | None = None) -> str:
        """The C, with the channel's number written as a literal or as the C expression ``k``."""
        if self.k is None:
            return self.c
        return self.c.format(k=k if k is not None else f"(real){self.k!r}")


@dataclass(frozen=True)
class Factor:
    """One term of a lobe's product, at its argument (None: the cell)."""

    term: Term
    arg: Known | None = None
    channel: int | None = None             # the channel it depends on (None: shared by all)


LOOP = "ch"
"""The channel of `Emitter` code written once for all channels: the C loop variable."""


class NotLoopable(ValueError):
    """A model whose channels cannot share one loop body (a per-channel parameter fixed in some
    channels and free in others): its kernels are written channel by channel."""


class Emitter:
    """Collects the C of a model: lines shared by all channels, and per channel the value and
    Jacobian expressions (``jac[ch]``: {column: [C terms]}).

    Unrolled (``position_of`` None), every channel gets its own code.  With ``position_of`` (slot
    name -> index in the parameter vector), per-channel code is written once for the loop
    variable ``ch``: ``body`` its lines, ``loop_value`` the value's terms, ``loop_jac`` {(column of
    channel 0, per channel): [C terms]} (a per-channel column is that plus ``ch``), ``loads`` the
    per-channel parameters read from ``P``, ``tables`` the channels' numbers of `Known`s."""

    def __init__(self, index_of, n_channels=3, position_of=None):
        self.lines: list[str] = []
        self.value: list[list[str]] = [[] for _ in range(n_channels)]
        self.jac: list[dict[int, list[str]]] = [{} for _ in range(n_channels)]
        self.n_channels = n_channels
        self.loop = position_of is not None
        self.body: list[str] = []
        self.loop_value: list[str] = []
        self.loop_jac: dict[tuple[int, bool], list[str]] = {}
        self.loads: dict[str, int] = {}          # C name -> index of channel 0 in P
        self.tables: dict[str, list] = {}         # C table name -> its value per channel
        self._index_of = index_of        # slot name -> column (None when fixed)
        self._position_of = position_of

    def channels(self):
        """The channels to write code for: each one, or `LOOP` once."""
        return [LOOP] if self.loop else range(self.n_channels)

    def line(self, s):
        """A C line shared by every channel."""
        self.lines.append(s)

    def channel_line(self, s):
        """A C line of one channel's code (in a loop, of the loop's body)."""
        (self.body if self.loop else self.lines).append(s)

    def tag(self, ch):
        """The suffix of a channel's C names."""
        return "_c" if ch == LOOP else f"_{ch}"

    def param(self, ch, name_of):
        """The C name of the slot ``name_of(ch)`` in channel ``ch``."""
        if ch != LOOP:
            return c_name(name_of(ch))
        names = [name_of(c) for c in range(self.n_channels)]
        if len(set(names)) == 1:
            return c_name(names[0])
        pos = [self._position_of(n) for n in names]
        if pos != list(range(pos[0], pos[0] + len(pos))):
            raise NotLoopable(f"{names[0]}: its channels are not consecutive parameters")
        cname = c_name(names[0].rsplit("_", 1)[0]) + "_c"
        self.loads[cname] = pos[0]
        return cname

    def known(self, ch, known_of, name):
        """The C of the `Known` ``known_of(ch)``; in a loop, its number from the table ``name``."""
        if ch != LOOP:
            return known_of(ch).code()
        ks = [known_of(c) for c in range(self.n_channels)]
        if len({k.c for k in ks}) != 1:
            raise NotLoopable(f"{name}: the channels' C differs beyond their number")
        if ks[0].k is None:
            return ks[0].c
        table = "KT_" + name
        self.tables[table] = [k.k for k in ks]
        return ks[0].code(f"{table}[ch]")

    def add(self, ch, expr):
        (self.loop_value if ch == LOOP else self.value[ch]).append(expr)

    def add_jac(self, ch, name_of, expr):
        """A term of the derivative with respect to the slot ``name_of(ch)``."""
        if ch != LOOP:
            col = self._index_of(name_of(ch))
            if col is not None:
                self.jac[ch].setdefault(col, []).append(expr)
            return
        names = [name_of(c) for c in range(self.n_channels)]
        cols = [self._index_of(n) for n in names]
        if all(c is None for c in cols):
            return
        if len(set(names)) == 1:
            key = (cols[0], False)
        elif None not in cols and cols == list(range(cols[0], cols[0] + len(cols))):
            key = (cols[0], True)
        else:
            raise NotLoopable(f"{names[0]}: fixed in some channels and free in others")
        self.loop_jac.setdefault(key, []).append(expr)


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
        shared_scale = len({(s.c, s.k) if s else None for s, _ in parts}) == 1
        shared = [f for f in parts[0][1] if f.channel is None]
        # the channel-independent part: S = scale * prod(shared factors), and dS
        calls = [self._emit_term(em, None, lambda c, f=f: f) for f in shared]
        base = [parts[0][0].code()] if shared_scale and parts[0][0] else []
        S = None
        dS: dict[str, str] = {}
        if calls or base:
            S = f"{pre}_shape"
            em.line(f"const real_v {S} = {' * '.join([v for v, _ in calls] + base)};")
            sums: dict[str, list[str]] = {}
            for i, (_, d) in enumerate(calls):
                others = [v for j, (v, _) in enumerate(calls) if j != i] + base
                for name_of, dv in d:
                    sums.setdefault(name_of(0), []).append(" * ".join([dv] + others))
            for name, terms in sums.items():
                dS[name] = f"{pre}_dshape_{name.split('.', 1)[1]}"
                em.line(f"const real_v {dS[name]} = {' + '.join(terms)};")
        n_own = sum(f.channel is not None for f in parts[0][1])
        for ch in em.channels():
            own = [self._emit_term(em, ch, lambda c, j=j: [f for f in parts[c][1] if f.channel is not None][j])
                   for j in range(n_own)]
            amp_of = lambda c: self.slot_name(self.amplitude.name, c)     # noqa: E731
            amp = em.param(ch, amp_of)
            k = [] if shared_scale or parts[0][0] is None else \
                [f"({em.known(ch, lambda c: parts[c][0], f'{pre}_scale')})"]
            if k:
                a = f"{pre}_scale{em.tag(ch)}"
                em.channel_line(f"const real {a} = {amp} * {k[0]};")
            else:
                a = amp
            rest = ([S] if S else []) + [v for v, _ in own]
            em.add(ch, " * ".join([a] + rest))
            em.add_jac(ch, amp_of, " * ".join(k + rest) or "(real_v)1")
            for name, dn in dS.items():
                em.add_jac(ch, lambda c, name=name: name, " * ".join([a, dn] + [v for v, _ in own]))
            for i, (_, d) in enumerate(own):
                others = ([S] if S else []) + [v for j, (v, _) in enumerate(own) if j != i]
                for name_of, dv in d:
                    em.add_jac(ch, name_of, " * ".join([a] + others + [dv]))

    def _emit_term(self, em, ch, factor_of):
        """Emit one factor's call, ``factor_of(ch)``, shared (``ch`` None and a factor of no
        channel) or channel ``ch``'s: (C value name, [(channel -> slot name, C derivative name)])."""
        fac = factor_of(0 if ch == LOOP else ch)
        term = fac.term
        tag = "" if fac.channel is None else em.tag(ch)
        line = em.line if fac.channel is None else em.channel_line
        base = f"{self.prefix}_{term.kind}{tag}"
        def name_of(p):
            return lambda c: self._inputs(term, factor_of(c).channel)[p]
        ins = [em.param(ch, name_of(p)) for p in term.inputs]
        ins += ["K_" + f"{self.prefix}.{term.kind}.{k}".replace(".", "_") for k in term.const_names]
        outs = [(name_of(p), f"{base}_d{p}") for p in term.inputs]
        if outs:
            line(f"real_v {', '.join(d for _, d in outs)};")
        arg = "&c" if fac.arg is None else \
            f"({em.known(ch, lambda c: factor_of(c).arg, f'{self.prefix}_{term.kind}_arg')})"
        line(f"const real_v {base} = {term.cfunc}({', '.join([arg, *ins, *(f'&{d}' for _, d in outs)])});")
        return base, outs
