"""What a lobe is: an amplitude per channel times a shape made of terms.

A lobe gives its parameters (``rho`` per channel, then its terms'), its float64
reference value and Jacobian per channel, and the OpenCL C that computes the
same.  Both sides call the terms through this class, so the structure of the
formula is written once per lobe (in diffuse.py, cooktorrance.py, diffraction.py).
"""
from __future__ import annotations

from dataclasses import dataclass

from brdfcl.model.lobes.spec import Param, Term

CH = ("r", "g", "b")


@dataclass(frozen=True)
class Slot:
    """One scalar of the model's parameter vector."""

    name: str                  # full name, e.g. "ct.F0_g"
    param: Param
    channel: int | None        # colour channel of a per-channel parameter
    lobe: str
    amplitude: bool = False    # the lobe's amplitude: the model is linear in it

    @property
    def cname(self):
        return "P_" + self.name.replace(".", "_")


class Emitter:
    """Collects the C lines and the per-channel value and Jacobian expressions of a model."""

    def __init__(self, index_of):
        self.lines: list[str] = []
        self.value: list[list[str]] = [[], [], []]
        self.jac: list[dict[int, list[str]]] = [{}, {}, {}]
        self._index_of = index_of        # slot name -> column (None when fixed)

    def line(self, s):
        self.lines.append(s)

    def add(self, ch, expr):
        self.value[ch].append(expr)

    def add_jac(self, ch, slot_name, expr):
        col = self._index_of(slot_name)
        if col is not None:
            self.jac[ch].setdefault(col, []).append(expr)


ROLES = ("diffuse", "diffraction", "reflection")
"""What a lobe stands for.  Analysis, lobe selection and the peak constraint ask for lobes by
role (``Model.lobes_with_role``), never by name or kind."""


class Lobe:
    """Base for the lobes.  ``prefix`` names its parameters (``ct.alpha``); ``role`` is one of
    ROLES.  The class's ``prefix`` is its kind's; a model holding a kind more than once gives
    the second ``ct2``, the third ``ct3``, ... (``Model`` sets the instance's ``prefix``)."""

    prefix: str
    role: str
    amplitude: Param
    terms: tuple[Term, ...] = ()

    @property
    def kind(self) -> str:
        """The kind's prefix (``ct`` for every Cook-Torrance lobe, also for one named ``ct2``)."""
        return type(self).prefix

    @property
    def tag(self) -> str:
        """Suffix that tells repeated lobes of one kind apart in C names ('' for the first)."""
        return self.prefix[len(self.kind):]

    def spec(self) -> str:
        """The lobe's part of a model string (``ggx:smith:schlick``)."""
        raise NotImplementedError

    def reference(self, cells, value, consts):
        """float64 value and Jacobian per channel: ([value], [{slot name: derivative}])."""
        raise NotImplementedError

    def emit(self, em: Emitter, ctx) -> None:
        """The OpenCL C that computes what ``reference`` does."""
        raise NotImplementedError

    def slots(self) -> list[Slot]:
        out = [Slot(f"{self.prefix}.{self.amplitude.name}_{CH[c]}", self.amplitude, c, self.prefix, True)
               for c in range(3)]
        for t in self.terms:
            for p in t.params:
                if p.per_channel:
                    out += [Slot(f"{self.prefix}.{p.name}_{CH[c]}", p, c, self.prefix) for c in range(3)]
                else:
                    out.append(Slot(f"{self.prefix}.{p.name}", p, None, self.prefix))
        return out

    def slot_name(self, pname, ch=None, term=None):
        per = any(p.name == pname and p.per_channel
                  for t in ((term,) if term else self.terms) if t for p in t.params)
        per = per or pname == self.amplitude.name
        return f"{self.prefix}.{pname}_{CH[ch]}" if per else f"{self.prefix}.{pname}"

    def const_names(self):
        return [f"{self.prefix}.{t.kind}.{k}" for t in self.terms for k in t.const_names]

    def consts(self, value):
        """Host constants of this lobe's terms: {full const name: value}."""
        out = {}
        for t in self.terms:
            if t.consts is not None:
                kw = {p.name: value(self.slot_name(p.name, term=t)) for p in t.params}
                for k, v in t.consts(**kw).items():
                    out[f"{self.prefix}.{t.kind}.{k}"] = v
        return out

    # --- calling a term on either side -------------------------------------------------------
    def ref_term(self, term, arg, value, consts, ch=None):
        """(value, {slot name: derivative}) of a term, numpy."""
        kw = {p: value(self.slot_name(p, ch, term)) for p in term.inputs}
        kw.update({k: consts[f"{self.prefix}.{term.kind}.{k}"] for k in term.const_names})
        v, grads = term.reference(arg, **kw)
        return v, {self.slot_name(p, ch, term): g for p, g in grads.items()}

    def emit_term(self, em, term, arg, tag, ch=None):
        """Emit a call; returns (C value name, {slot name: C derivative name})."""
        base = f"{self.prefix}_{term.kind}{'' if ch is None else '_' + CH[ch]}{tag}"
        ins = [Slot(self.slot_name(p, ch, term), None, None, "").cname for p in term.inputs]
        ins += ["K_" + f"{self.prefix}.{term.kind}.{k}".replace(".", "_") for k in term.const_names]
        outs = {self.slot_name(p, ch, term): f"{base}_d{p}" for p in term.inputs}
        if outs:
            em.line(f"real_v {', '.join(outs.values())};")
        args = [arg] + ins + [f"&{d}" for d in outs.values()]
        em.line(f"const real_v {base} = {term.cfunc}({', '.join(args)});")
        return base, outs
