"""OpenCL source for one model, specialised from its lobe descriptions.

Only the terms the model uses are included; only free parameters get a Jacobian
column; J^T J accumulates only the pairs that are structurally non-zero in
some channel (an amplitude of channel c touches channel c alone).  Fixed
parameters are plain constants that the compiler folds away.
"""
from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from functools import cache, lru_cache
from pathlib import Path

from brdfcl._cache import generated
from brdfcl.kernels import inline_math
from brdfcl.kernels.terms import c_source, cell_source
from brdfcl.model.compose import Model
from brdfcl.model.lobes.lobe import Emitter, NotLoopable
from brdfcl.model.metrics import IMPLEMENTED_METRICS, check_metric
from brdfcl.model.terms import REGISTRY
from brdfcl.model.terms.keys import sympy_version


def kernel_dir() -> Path:
    """The OpenCL sources: the folder of this module (they ship in the wheel as package data)."""
    here = Path(__file__).resolve().parent
    if not (here / "model.cl.mako").is_file():
        raise FileNotFoundError(f"brdfcl's OpenCL kernels are missing from {here}: reinstall brdfcl")
    return here


@cache
def read_kernel(rel: str) -> str:
    """A kernel source file (relative to kernel_dir()), read once per process."""
    return (kernel_dir() / rel).read_text()


@lru_cache(maxsize=1)
def kernel_sources_hash() -> str:
    """A hash of what the kernels are made from: every kernel source and the template, the code
    that writes terms and lobes as C (this folder's and brdfcl.model's modules), the module of every
    registered term (a user's own included), SymPy's version, and the metrics' C expressions.
    Decisions cached about compiled programs (brdfcl.device.width) are stale once any of them
    changes.  Hashing the inputs, not the generated C, keeps SymPy's generation of every term
    (seconds) out of every start-up."""
    h = hashlib.sha1(sympy_version().encode())
    for p in sorted(kernel_dir().rglob("*")):
        if p.suffix in (".cl", ".mako"):
            h.update(p.relative_to(kernel_dir()).as_posix().encode() + b"\0" + p.read_bytes())
    here = Path(__file__).resolve().parent
    files = set(here.glob("*.py")) | set((here.parent / "model").rglob("*.py"))
    for kind in REGISTRY.values():
        for t in kind.values():
            h.update(f"{t.kind}\0{t.name}\0{t.origin}".encode())
            origin = getattr(sys.modules.get(t.origin), "__file__", None)
            if origin:
                files.add(Path(origin))
            else:                   # registered from no file (a notebook, exec): its generated C
                h.update(c_source(t).encode())
    for f in sorted(Path(f).resolve() for f in files):
        h.update(f.name.encode() + b"\0" + f.read_bytes())
    for m in IMPLEMENTED_METRICS.values():
        h.update("\0".join((m.name, *m.c("x", "g"))).encode())
    return h.hexdigest()


KEEP_RENDERED = 64
"""Rendered programs kept on disk (the newest; one per model and kernel options)."""


@lru_cache(maxsize=1)
def _template():
    from mako.template import Template  # here: importing and compiling it costs a start-up 0.1 s
    return Template(filename=str(kernel_dir() / "model.cl.mako"), strict_undefined=True)


@dataclass(frozen=True)
class KernelOptions:
    real: str = "float"         # "float" or "double"
    vw: int = 8                 # cells per vector (1 on GPUs)
    local: int = 1              # work-group size along cells
    chunk: int = 256            # vectors per work-group
    metric: str = "log"
    cosw: bool = True           # cos(theta_i) factor in the residual
    channel_loop: bool | None = None    # one loop over channels (None: from LOOP_FROM channels on)

    def __post_init__(self):
        check_metric(self.metric)
        if self.real not in ("float", "double"):
            raise ValueError(f"precision '{self.real}': valid are float, double")
        if self.vw not in (1, 2, 4, 8, 16) or self.local < 1 or self.local & (self.local - 1):
            raise ValueError(f"vector width {self.vw} / local size {self.local}: powers of two expected")


MEAT_MAX_FREE = 32
"""Free parameters up to which a program holds the ``meat`` kernel (its k (k + 1) / 2 sums in
each work-item); a larger model's M is summed by the float64 reference (brdfcl.optim.uncertainty)."""


KERNELS = ("target", "loss", "grad", "jtj", "errors", "predict")
"""The kernels of every program (model.cl.mako)."""


def kernel_names(model: Model) -> tuple[str, ...]:
    """The kernels ``model``'s program holds: KERNELS, and ``meat`` up to MEAT_MAX_FREE free
    parameters."""
    return KERNELS + (("meat",) if model.n_free <= MEAT_MAX_FREE else ())


LOOP_FROM = 4
"""Models of this many channels or more are written as one loop over their channels: an
unrolled 31-band program is 31 copies of the per-channel code, which PoCL takes tens of seconds
to compile; RGB models keep the unrolled code (constants folded per channel)."""


def emit(model: Model, loop: bool = False) -> Emitter:
    """The C of ``model``'s lobes, channel by channel or (``loop``) once for a loop over channels
    (`NotLoopable` where the channels cannot share one body)."""
    em = Emitter(model.column, model.n_channels, model.position if loop else None)
    for lb in model.lobes:
        lb.emit(em)
    return em


def _loop_emitter(model: Model, opt: KernelOptions) -> Emitter | None:
    want = opt.channel_loop if opt.channel_loop is not None else model.n_channels >= LOOP_FROM
    if not want:
        return None
    try:
        return emit(model, loop=True)
    except NotLoopable:
        if opt.channel_loop:
            raise
        return None


def _loop_tables(em: Emitter, pairs) -> tuple[list, dict]:
    """The loop body's Jacobian columns and J^T J entries: ([(key, C column)], {(key a, key b): C
    index into the kernels' pair order}); a per-channel entry indexes a table by ``ch``."""
    n = em.n_channels
    keys = sorted(em.loop_jac)
    col = {k: (lambda c, k=k: k[0] + (c if k[1] else 0)) for k in keys}
    index = {ab: i for i, ab in enumerate(pairs)}
    seen = set()
    out = {}
    for a in keys:
        for b in keys:
            if col[b](0) < col[a](0):
                continue
            idx = []
            for c in range(n):
                ab = (col[a](c), col[b](c))
                seen.add(ab)
                idx.append(index[ab])
            if a[1] or b[1]:
                name = f"PAIR_{len(em.tables)}"
                em.tables[name] = idx
                out[(a, b)] = f"{name}[ch]"
            else:
                out[(a, b)] = str(idx[0])
    assert seen == set(pairs), "the loop's J^T J entries are the kernels' pairs"
    cols = [(k, f"{k[0]} + ch" if k[1] else str(k[0])) for k in keys]
    return cols, out


def term_sources(model: Model) -> list[str]:
    """The OpenCL functions of the terms a model uses, each once, in the order first used."""
    return [c_source(t) for t in dict.fromkeys(t for lb in model.lobes for t in lb.terms)]


def render(model: Model, opt: KernelOptions) -> str:
    """The program's OpenCL source: model.cl.mako rendered for ``model`` and ``opt``, kept in
    brdfcl's cache under a hash of everything it is rendered from (a second process needs no Mako)."""
    em = emit(model)
    cols = set()
    pairs = jtj_pairs(model)
    for ch in range(model.n_channels):
        cols |= set(em.jac[ch])
    assert cols == set(range(model.n_free)), "every free parameter needs a Jacobian column"
    lem = _loop_emitter(model, opt)
    loop_cols, loop_pairs = _loop_tables(lem, pairs) if lem else ([], {})
    keys = [k for k, _ in loop_cols]
    vec = "" if opt.vw == 1 else str(opt.vw)
    fit_g, fit_dg = IMPLEMENTED_METRICS[opt.metric].c("x", "g")    # metric_g / metric_dg
    kw = dict(
        spec=model.spec, real=opt.real, vw=opt.vw, wg=opt.local, chunk=opt.chunk,
        metric=opt.metric, cosw=opt.cosw, metric_g=fit_g, metric_dg=fit_dg,
        reported=[(m.name, m.c("xp")[0], m.c("xm")[0]) for m in IMPLEMENTED_METRICS.values()],
        real_v=opt.real + vec, cond_v=("int" if opt.real == "float" else "long") + vec,
        common=read_kernel("common.cl") + "\n" + cell_source(), sources=term_sources(model),
        inline_math=[inline_math.c_source(t, i) for t, i in dict.fromkeys(
            ((opt.real + vec, "int" + vec), ("float", "int")))] if opt.real == "float" else [],
        inline_names=inline_math.NAMES,
        slots=model.slots, n_slots=model.n_params, n_ch=model.n_channels,
        consts=["K_" + k.replace(".", "_") for k in model.const_names],
        n_prm=model.n_params + len(model.const_names), n_free=model.n_free,
        meat="meat" in kernel_names(model), n_meat=n_outputs(model, len(pairs))["meat"],
        lines=em.lines, value=em.value, jac=em.jac, pairs=pairs, ch_loop=lem is not None,
        loop_lines=lem.lines if lem else [], body=lem.body if lem else [],
        loop_value=lem.loop_value if lem else [],
        loop_jac=[(i, c, lem.loop_jac[k]) for i, (k, c) in enumerate(loop_cols)] if lem else [],
        loop_pairs=[(keys.index(ka), keys.index(kb), c) for (ka, kb), c in loop_pairs.items()],
        loads=sorted(lem.loads.items()) if lem else [],
        tables=[(n, "int" if n.startswith("PAIR_") else "real", v) for n, v in lem.tables.items()] if lem else [])
    key = hashlib.sha1((kernel_sources_hash() + repr(sorted(kw.items()))).encode()).hexdigest()[:24]
    return generated("kernel", key, lambda: _template().render(**kw), keep=KEEP_RENDERED)


def jtj_pairs(model: Model):
    """The (a, b), a <= b, entries of J^T J that are non-zero in some channel, in kernel order."""
    em = emit(model)
    return sorted({(a, b) for ch in range(model.n_channels) for a in em.jac[ch] for b in em.jac[ch] if b >= a})


def n_outputs(model: Model, n_pairs: int) -> dict:
    """Partial sums each kernel writes per evaluation and work-group."""
    return {"loss": 1, "grad": 1 + model.n_free, "jtj": 1 + model.n_free + n_pairs,
            "errors": len(IMPLEMENTED_METRICS) + 2,      # sum w r^2 per metric, sum w x_m^2, sum w
            "meat": model.n_free * (model.n_free + 1) // 2}
