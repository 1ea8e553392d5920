"""A model: a sum of lobes, its parameter vector, and its float64 reference.

Model strings join lobes with ``+``; options follow a lobe after ``:``, e.g.
``diffuse+diffraction:hp+ggx:smith:schlick``.  Lobes: ``diffuse``,
``diffraction[:PSD][:FRESNEL]``, and a Cook-Torrance lobe named by its
distribution ``ggx|gtr|abc|beckmann|sgd|epd[:SHADOWING][:FRESNEL]``.  A kind may appear any
number of times: its lobes' parameters are prefixed ``ct``, ``ct2``, ``ct3``, ... in order
(``diffuse``, ``diffuse2``; ``diffraction``, ``diffraction2``).  Each lobe has a role
(diffuse, diffraction, reflection) by which the rest of the package finds it.

The optimiser works on ``x``: the free parameters, in log space where the
parameter is flagged ``log`` (alpha, a, amplitudes).  Everything the kernels
and exports need (slot order, bounds, host constants) is derived here from
the lobe descriptions.

One module (~270 lines): parsing a model string, its parameter slots, its spaces and its
reference are the one description that the kernels, optimiser and exports all read.
"""
from __future__ import annotations

import difflib
from functools import cached_property

import numpy as np

from brdfcl.model.lobes import LAMBDAS, REGISTRY, CookTorrance, Diffraction, Diffuse
from brdfcl.model.lobes.lobe import ROLES, Lobe, Slot, channel_names
from brdfcl.model.terms import shadowing_families

DEFAULT_MODEL = "diffuse+diffraction+ggx"
CT_NDFS = tuple(REGISTRY["ndf"])
SHADOWINGS = tuple(shadowing_families())
"""The shadowing words of a model string (each term's ``family``)."""


class ModelError(ValueError):
    """An invalid model string or option; the message lists the valid choices."""


def _valid_text():
    return (f"lobes: diffuse, diffraction[:{'|'.join(REGISTRY['psd'])}][:FRESNEL], "
            f"{'|'.join(CT_NDFS)}[:{'|'.join(SHADOWINGS)}][:FRESNEL]; "
            f"FRESNEL: {'|'.join(REGISTRY['fresnel'])}")


def _did_you_mean(word: str, valid, cutoff: float = 0.6) -> str:
    """"; did you mean 'X'?" for the valid word nearest ``word`` (difflib's similarity at least
    ``cutoff``), or ";"."""
    close = difflib.get_close_matches(word, list(valid), n=1, cutoff=cutoff)
    return f"; did you mean '{close[0]}'?" if close else ";"


def _bad_option(text: str, option: str, kinds: dict) -> ModelError:
    """A lobe option that is none of the lobe's (with the nearest that is), or a second one of a
    kind; ``kinds``: what the kinds are called -> their options."""
    for what, options in kinds.items():
        if option in options:
            return ModelError(f"'{text}': two {what}; give one; {_valid_text()}")
    valid = [o for options in kinds.values() for o in options]
    return ModelError(f"'{text}': bad option '{option}'{_did_you_mean(option, valid)} {_valid_text()}")


def parse_lobe(text: str, lambdas=LAMBDAS) -> Lobe:
    name, *opts = [t.strip().lower() for t in text.split(":")]
    if name == "diffuse":
        if opts:
            raise ModelError(f"'{text}': diffuse takes no options")
        return Diffuse(lambdas=lambdas)
    if name == "diffraction":
        kw = {}
        for o in opts:
            key = "psd" if o in REGISTRY["psd"] else "fresnel" if o in REGISTRY["fresnel"] else None
            if key is None or key in kw:
                raise _bad_option(text, o, {"PSDs": REGISTRY["psd"], "Fresnel terms": REGISTRY["fresnel"]})
            kw[key] = o
        return Diffraction(lambdas=lambdas, **kw)
    if name in CT_NDFS:
        kw = {}
        for o in opts:
            if o in SHADOWINGS and "shadowing" not in kw:
                kw["shadowing"] = o
            elif o in REGISTRY["fresnel"] and "fresnel" not in kw:
                kw["fresnel"] = o
            else:
                raise _bad_option(text, o, {"shadowing terms": SHADOWINGS,
                                            "Fresnel terms": REGISTRY["fresnel"]})
        try:
            return CookTorrance(name, lambdas=lambdas, **kw)
        except (ValueError, KeyError) as e:
            raise ModelError(f"'{text}': {e}") from None
    where = f" in '{text}'" if text.strip().lower() != name else ""
    raise ModelError(f"unknown lobe '{name}'{where}{_did_you_mean(name, ['diffuse', 'diffraction', *CT_NDFS])} "
                     f"{_valid_text()}")


def lobe_prefixes(kinds):
    """Parameter prefixes of lobes of the given kinds, in order: a kind's first lobe has the kind's
    prefix (``ct``), its second ``ct2``, its third ``ct3``, ..."""
    seen: dict[str, int] = {}
    out = []
    for k in kinds:
        seen[k] = seen.get(k, 0) + 1
        out.append(k if seen[k] == 1 else f"{k}{seen[k]}")
    return out


def _frozen(a):
    a.setflags(write=False)
    return a


class Model:
    """A sum of lobes with its parameter slots; optionally some parameters fixed."""

    def __init__(self, spec: str = DEFAULT_MODEL, fixed: dict | None = None, lambdas=LAMBDAS,
                 prefixes=None):
        if not spec or not spec.strip():
            raise ModelError(f"empty model; {_valid_text()}")
        self.lobes = [parse_lobe(t, lambdas) for t in spec.split("+")]
        if prefixes is None:
            prefixes = lobe_prefixes([lb.kind for lb in self.lobes])
        if len(prefixes) != len(self.lobes) or len(set(prefixes)) != len(prefixes):
            raise ModelError(f"'{spec}': lobe prefixes {', '.join(prefixes)} are not one distinct "
                             f"prefix per lobe")
        for lb, pre in zip(self.lobes, prefixes):
            lb.prefix = pre
        self.lambdas = tuple(lambdas)
        self.slots: list[Slot] = [s for lb in self.lobes for s in lb.slots()]
        self.names = [s.name for s in self.slots]
        self._pos = {n: i for i, n in enumerate(self.names)}
        self.fixed = {}
        for k, v in (fixed or {}).items():
            if k not in self._pos:
                hint = _did_you_mean(k, self.names, cutoff=0.75)      # ct.F0_r is no typo of ct.rho_r
                raise ModelError(f"cannot fix '{k}': not a parameter of {self.spec}{hint} "
                                 f"parameters: {', '.join(self.names)}")
            self.fixed[k] = float(v)
        self.lo = _frozen(np.array([s.param.lo for s in self.slots]))
        self.hi = _frozen(np.array([s.param.hi for s in self.slots]))
        self.log = _frozen(np.array([s.param.log for s in self.slots]))
        self.free = np.array([n not in self.fixed for n in self.names])
        self.amplitude = _frozen(np.array([s.amplitude for s in self.slots]))
        self.free_index = np.flatnonzero(self.free)
        self.const_names = [k for lb in self.lobes for k in lb.const_names()]

    # --- description --------------------------------------------------------------------------
    @property
    def spec(self) -> str:
        return "+".join(lb.spec() for lb in self.lobes)

    def __repr__(self):
        return f"Model('{self.spec}', {len(self.free_index)} free parameters)"

    @property
    def n_channels(self) -> int:
        return len(self.lambdas)

    @property
    def channels(self) -> tuple[str, ...]:
        """Channel names as parameter names use them (r, g, b; or wavelengths: 550nm)."""
        return channel_names(self.lambdas)

    @property
    def n_params(self):
        return len(self.slots)

    @property
    def n_free(self):
        return len(self.free_index)

    def position(self, name):
        """Index of a parameter in the parameter vector (the kernels' ``P``)."""
        return self._pos[name]

    def column(self, name):
        """Column of a parameter in the free (Jacobian) vector, None if fixed."""
        i = self._pos[name]
        return None if not self.free[i] else int(np.searchsorted(self.free_index, i))

    def has(self, prefix):
        return any(lb.prefix == prefix for lb in self.lobes)

    def lobes_with_role(self, role) -> list[Lobe]:
        """The lobes that play ``role`` (one of brdfcl.model.lobes.lobe.ROLES), in model order."""
        if role not in ROLES:
            raise ValueError(f"unknown lobe role '{role}'; roles: {', '.join(ROLES)}")
        return [lb for lb in self.lobes if lb.role == role]

    def prefixes_with_role(self, *roles) -> tuple[str, ...]:
        """Parameter prefixes of the lobes playing any of ``roles`` (for ``only_lobes``)."""
        return tuple(lb.prefix for r in roles for lb in self.lobes_with_role(r))

    def has_role(self, role) -> bool:
        return bool(self.lobes_with_role(role))

    def submodel(self, lobes):
        """The model made of some of this model's lobes, with their parameter names (and fixed
        values); None when ``lobes`` is empty."""
        lobes = list(lobes)
        if not lobes:
            return None
        pre = [lb.prefix for lb in lobes]
        fixed = {k: v for k, v in self.fixed.items() if k.split(".", 1)[0] in pre}
        return Model("+".join(lb.spec() for lb in lobes), fixed=fixed, lambdas=self.lambdas, prefixes=pre)

    def defaults(self):
        v = np.array([s.param.default for s in self.slots])
        for k, val in self.fixed.items():
            v[self._pos[k]] = val
        return v

    def as_dict(self, values):
        return {n: float(v) for n, v in zip(self.names, values)}

    def only_lobes(self, params, keep):
        """Value vector of ``params`` (by name) with every amplitude outside the lobes ``keep``
        (their prefixes; None keeps all) set to zero: one lobe's part of a fit."""
        v = np.array([params[n] for n in self.names])
        if keep is not None:
            for i, s in enumerate(self.slots):
                if s.lobe not in keep and s.amplitude:
                    v[i] = 0.0
        return v

    # --- host constants --------------------------------------------------------------------------
    def consts(self, values):
        """Parameter-only constants (normalisations) for each value vector: (..., n_consts)."""
        values = np.asarray(values, dtype=np.float64)
        if not self.const_names:
            return np.zeros(values.shape[:-1] + (0,))
        out = {}
        for lb in self.lobes:
            out.update(lb.consts(lambda name: values[..., self._pos[name]]))
        return np.stack([np.broadcast_to(out[k], values.shape[:-1]) for k in self.const_names], -1)

    # --- optimiser space ------------------------------------------------------------------------
    def to_x(self, values):
        v = np.asarray(values, dtype=np.float64)[..., self.free_index]
        lg = self.log[self.free_index]
        return np.where(lg, np.log(np.where(lg, v, 1.0)), v)

    def from_x(self, x, base=None):
        """Full value vectors from optimiser vectors (fixed parameters from ``base`` or defaults)."""
        x = np.asarray(x, dtype=np.float64)
        v = np.broadcast_to(self.defaults() if base is None else base, x.shape[:-1] + (self.n_params,)).copy()
        lg = self.log[self.free_index]
        v[..., self.free_index] = np.where(lg, np.exp(x), x)
        return np.clip(v, self.lo, self.hi)

    def dvalue_dx(self, values):
        """d value / d x for the free parameters (chain rule of the log transform)."""
        v = np.asarray(values, dtype=np.float64)[..., self.free_index]
        return np.where(self.log[self.free_index], v, 1.0)

    @cached_property
    def search_x_lo(self):
        """The global search's candidate box in x space (each Param's search range)."""
        return _frozen(self.to_x(np.array([s.param.search_range[0] for s in self.slots])))

    @cached_property
    def search_x_hi(self):
        return _frozen(self.to_x(np.array([s.param.search_range[1] for s in self.slots])))

    @cached_property
    def x_lo(self):
        return _frozen(self.to_x(self.lo))

    @cached_property
    def x_hi(self):
        return _frozen(self.to_x(self.hi))

    # --- reference evaluation -------------------------------------------------------------------
    def reference(self, cells, values, jacobian=True):
        """Model value (3, n) and Jacobian (3, n, n_free) w.r.t. the free natural parameters.

        ``values`` is one parameter vector, or one per cell (n, n_params).

        Computed in the precision of the cells (float64 is the reference; float32
        cells give the float32 numpy version the benchmark compares against)."""
        dt = cells.sh.dtype
        values = np.asarray(values, dtype=np.float64)
        consts = dict(zip(self.const_names, np.moveaxis(self.consts(values).astype(dt), -1, 0)))
        values = values.astype(dt)

        def value(name):
            return values[..., self._pos[name]]

        p = np.zeros((self.n_channels, len(cells)), dtype=dt)
        J = np.zeros((self.n_channels, len(cells), self.n_free), dtype=dt) if jacobian else None
        for lb in self.lobes:
            vals, jacs = lb.reference(cells, value, consts)
            for ch in range(self.n_channels):
                p[ch] += vals[ch]
                if jacobian:
                    for name, d in jacs[ch].items():
                        col = self.column(name)
                        if col is not None:
                            J[ch, :, col] += d
        return (p, J) if jacobian else p
