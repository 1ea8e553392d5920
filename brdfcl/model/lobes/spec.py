"""How lobes and their terms are described, once.

A `Param` is one model parameter (bounds, default, log-space flag, unit).  A
`Term` is one factor of a lobe (a D, G, F or PSD): its parameters, the OpenCL
source file and function that evaluate it with derivatives, and the float64
numpy reference of the same formula.  Everything else (kernel specialisation,
the optimiser's vector, exports, docs) is derived from these descriptions.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable


@dataclass(frozen=True)
class Param:
    name: str
    lo: float
    hi: float
    default: float
    log: bool = False
    unit: str = ""
    doc: str = ""
    per_channel: bool = False     # one value per colour channel (amplitudes, F0, eta/k of metals)
    search: tuple | None = None   # where the global search draws candidates (default: the bounds)

    def __post_init__(self):
        assert self.lo < self.hi and self.lo <= self.default <= self.hi, self
        assert not self.log or self.lo > 0, self
        if self.search is not None:
            assert self.lo <= self.search[0] < self.search[1] <= self.hi, self

    @property
    def search_range(self):
        return self.search or (self.lo, self.hi)


@dataclass(frozen=True)
class Term:
    """One factor of a lobe, evaluated per cell with its derivatives.

    ``reference(cells, **params) -> (value, {param: d value / d param})`` is the
    float64 ground truth; the C function ``cfunc`` in ``kernel`` has the
    signature ``real_v cfunc(const cell_t *c | real_v f, params..., consts...,
    real_v *d_param...)`` and must agree with it.  ``consts(**params)`` computes
    parameter-only quantities on the host (normalisation constants), returning
    ``({name: value}, {name: {param: derivative}})``."""

    kind: str                       # 'ndf', 'shadowing', 'fresnel', 'psd'
    name: str
    params: tuple[Param, ...]
    kernel: str                     # file under kernels/
    cfunc: str
    reference: Callable
    cite: str = ""
    consts: Callable | None = None
    const_names: tuple[str, ...] = ()
    uses: tuple[str, ...] = ()      # parameters read from another term (G reads D's alpha)
    ndfs: tuple[str, ...] = ()      # shadowing: the D terms it is defined for (empty: any)
    per_channel: bool = False       # evaluated once per channel (per-channel parameters)
    doc: str = ""

    @property
    def inputs(self) -> tuple[str, ...]:
        """Parameter names the function takes, in C argument order."""
        return tuple(p.name for p in self.params) + self.uses


REGISTRY: dict[str, dict[str, Term]] = {"ndf": {}, "shadowing": {}, "fresnel": {}, "psd": {}}


def register(term: Term) -> Term:
    REGISTRY[term.kind][term.name] = term
    return term
