"""A fitted model evaluated with Dr.Jit: the BRDF and the sampling densities of a Mitsuba 3 BSDF.

Each term is the function printed from its formula (brdfcl.report.export.drjit_source); the lobes
compose them as the kernels and the float64 reference do (``Lobe.parts``: amplitude x scale x
factors, factors that do not depend on the channel evaluated once).  Parameters are Dr.Jit
scalars (one ``Float`` per slot of the model, by its name), so that a renderer can expose them and
Dr.Jit's AD differentiates through every term.  The host constants (normalisations, the Smith
series of GTR and ABC) are computed on the host in float64, as for the kernels, and enter as
``K + sum_p dK/dp (p - detach(p))``: the value is K and the gradient is the analytic one.  That
expression is built each time a term is evaluated, not when the parameters change: Mitsuba's
differentiable render is a custom operation that follows only the edges inside it.

Directions are in the local shading frame (n = z); ``cells(wi, wo)`` takes Dr.Jit 3-vectors (or
anything with ``x``, ``y``, ``z``) and says where a pair has a value (both above the horizon);
``DrjitModel.brdf_cells`` evaluates the model at those cells.
"""
from __future__ import annotations

from types import SimpleNamespace

import drjit as dr
import numpy as np

from brdfcl.model.compose import Model
from brdfcl.model.terms import REGISTRY
from brdfcl.report.export.drjit_source import HELPERS, cell_source, term_args, term_source

_H_MIN = 1e-7
"""Below this |wi + wo| (exact back-scattering to the opposite side) there is no half-vector."""


def _compile(source: str, name: str, what: str):
    namespace: dict = {"dr": dr}
    exec(compile(HELPERS, "<brdfcl drjit helpers>", "exec"), namespace)
    exec(compile(source, f"<brdfcl drjit {what}>", "exec"), namespace)
    return namespace[name]


_functions: dict = {}


def term_function(term):
    """The compiled Dr.Jit function of one term (``term_args(term)`` are its arguments)."""
    key = (term.kind, term.name, term.origin)
    if key not in _functions:
        _functions[key] = _compile(term_source(term), "value", f"{term.kind} {term.name}")
    return _functions[key]


_derived = None


def cells(wi, wo):
    """The per-cell quantities (the five stored and every DERIVED one) of direction pairs, and
    where the pair has a half-vector above the horizon on both sides."""
    global _derived
    if _derived is None:
        _derived = _compile(cell_source(), "derived", "cells")
    hx, hy, hz = wi.x + wo.x, wi.y + wo.y, wi.z + wo.z
    n2 = hx * hx + hy * hy + hz * hz
    valid = (wi.z > 0) & (wo.z > 0) & (n2 > _H_MIN * _H_MIN)
    inv = dr.rsqrt(dr.select(valid, n2, 1.0))
    # sin theta_h from the tangential part: exact at the peak in float32, where 1 - ch^2 is not
    sh = dr.sqrt(hx * hx + hy * hy) * inv
    ch = dr.select(valid, hz * inv, 1.0)
    cd = dr.select(valid, (wi.x * hx + wi.y * hy + wi.z * hz) * inv, 1.0)
    ci = dr.select(valid, wi.z, 1.0)
    co = dr.select(valid, wo.z, 1.0)
    base = {"sh": sh, "ch": ch, "cd": cd, "ci": ci, "co": co}
    return SimpleNamespace(**base, **_derived(**base)), valid


class DrjitModel:
    """A model and its parameter values, evaluated with Dr.Jit.

    ``params`` maps each slot name (``ct.alpha``) to a Dr.Jit ``Float`` of one value; change them
    in place (or through Mitsuba's scene parameters) and call `update` so that the host constants
    follow."""

    def __init__(self, model: Model, values, Float):
        self.model = model
        self.Float = Float
        values = np.asarray(values, dtype=np.float64)
        self.params = {n: Float(float(v)) for n, v in zip(model.names, values)}
        self.consts: dict = {}
        self.update()

    def host_values(self) -> dict[str, float]:
        """The current parameter values as Python floats."""
        return {n: _scalar(p) for n, p in self.params.items()}

    def update(self) -> None:
        """Recompute the host constants from the current parameters (float64, on the host)."""
        now = self.host_values()
        self.consts = {}
        for lb in self.model.lobes:
            self.consts.update(lb.consts(lambda name: now[name]))

    def _const(self, lb, term, name):
        """A host constant as the term reads it: ``K + sum_p dK/dp (p - detach(p))``, made where it
        is read, so that the edge from p to K lies in the graph that reads it (a render's)."""
        key = f"{lb.prefix}.{term.kind}.{name}"
        if name not in term.host:
            return float(self.consts[key])
        v = self.Float(float(self.consts[key]))
        for p, slot in lb._inputs(term, None).items():
            d = float(self.consts[f"{lb.prefix}.{term.kind}.d{name}_{p}"])
            if d != 0.0 and dr.grad_enabled(self.params[slot]):
                v = v + d * (self.params[slot] - dr.detach(self.params[slot]))
        return v

    def _term(self, lb, term, arg, channel):
        slots = lb._inputs(term, channel)
        values = []
        for a in term_args(term):
            if a in slots:
                values.append(self.params[slots[a]])
            elif a in term.const_names:
                values.append(self._const(lb, term, a))
            elif a == "f":
                values.append(arg)
            else:
                values.append(getattr(arg, a))
        return term_function(term)(*values)

    def brdf_cells(self, c) -> list:
        """f per channel (1/sr) at cells ``c`` (a namespace of the per-cell quantities)."""
        out: list = [0.0] * self.model.n_channels
        for lb in self.model.lobes:
            done: dict = {}
            for ch in range(self.model.n_channels):
                scale, factors = lb.parts(ch)
                v = self.params[lb.slot_name(lb.amplitude.name, ch)]
                if scale is not None:
                    v = v * scale.ref(c)
                for fac in factors:
                    key = (fac.term.kind, fac.term.name, fac.channel)
                    if key not in done:
                        arg = c if fac.arg is None else fac.arg.ref(c)
                        done[key] = self._term(lb, fac.term, arg, fac.channel)
                    v = v * done[key]
                out[ch] = out[ch] + v
        return out


def ndf_density(kind: str, alpha: float, ch, t2):
    """D(h) of the half-vector distribution ``kind`` (an NDF's ``sampled_as``: ggx, beckmann) at
    cos theta_h and tan^2 theta_h, from the NDF's own printed formula."""
    term = REGISTRY["ndf"][kind]
    c = SimpleNamespace(ch=ch, t2=t2)
    return term_function(term)(*(alpha if a == "alpha" else getattr(c, a) for a in term_args(term)))


def _scalar(x) -> float:
    """A Dr.Jit scalar (an array of one value, or a Python float in scalar variants) on the host."""
    if dr.is_array_v(x):
        return float(x[0]) if dr.width(x) >= 1 else float("nan")
    return float(x)
