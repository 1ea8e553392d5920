"""The global stage: local optima on a coarse cell set, then the best start per material.

Global search (``FitOptions.global_method``):
* ``lds`` (default): Sobol candidates in the search box, evaluated for all materials in one
  launch, then nlopt local searches (LD_LBFGS) from the defaults and the best few per material, in
  lockstep; a batched form of MLSL with low-discrepancy starts.
* ``mlsl``: nlopt G_MLSL_LDS with LD_LBFGS local searches, in lockstep.
* ``crs2``: nlopt GN_CRS2_LM, in lockstep.
* ``none``: start the local refinement from the default values.
"""
from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass

import nlopt
import numpy as np

from brdfcl.data.sobol import sobol_points
from brdfcl.optim.lockstep import Problem, run_lockstep
from brdfcl.optim.objective import Objective, Target
from brdfcl.optim.options import FitOptions
from brdfcl.optim.result import StageResult
from brdfcl.optim.status import Status


def _quiet(line: str) -> None:
    pass


def material_seed(seed: int, name: str) -> int:
    """nlopt's seed for one material: fixed by the fit's seed and the name, not by the batch."""
    return (seed * 1000003 + zlib.crc32(name.encode())) % (2 ** 31)


@dataclass
class _Batched:
    """run_lockstep's callback: evaluate every posted point, each for its start's material."""

    objective: Objective
    target: Target
    mats: np.ndarray                 # material of each lockstep problem
    penalty: bool

    def __call__(self, xs: np.ndarray, need: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mats = self.mats[ids]
        if need.any():
            return self.objective.loss_grad(self.target, xs, mats, penalty=self.penalty)
        return self.objective.loss(self.target, xs, mats, penalty=self.penalty), np.zeros_like(xs)


def _optimiser(method: str, k: int, lo: np.ndarray, hi: np.ndarray, local_maxeval: int) -> nlopt.opt:
    """A configured nlopt optimiser for one start (objective set by run_lockstep)."""
    algo = {"lds": nlopt.LD_LBFGS, "mlsl": nlopt.G_MLSL_LDS, "crs2": nlopt.GN_CRS2_LM}[method]
    opt = nlopt.opt(algo, k)
    opt.set_lower_bounds(lo)
    opt.set_upper_bounds(hi)
    opt.set_maxeval(local_maxeval if method == "lds" else 10 * local_maxeval)
    opt.set_ftol_rel(1e-7)
    if algo == nlopt.G_MLSL_LDS:
        loc = nlopt.opt(nlopt.LD_LBFGS, k)
        loc.set_ftol_rel(1e-6)
        loc.set_maxeval(local_maxeval // 2)
        opt.set_local_optimizer(loc)
    return opt


def _lds_starts(objective: Objective, target: Target, n: int, options: FitOptions, penalty: bool,
                log: Callable[[str], None]) -> tuple[list[tuple[int, np.ndarray]], int]:
    """The defaults and the best ``n_starts`` Sobol candidates per material: ([(material, x)],
    candidates evaluated per material)."""
    sp = objective.spaces
    sob = sobol_points(objective.model.n_free, options.n_candidates, options.seed)
    slo, shi = sp.search_box
    cand = np.vstack([sp.default_x(1), slo + sob * (shi - slo)])
    nc = cand.shape[0]
    L = objective.loss(target, np.tile(cand, (n, 1)), np.repeat(np.arange(n), nc), penalty=penalty)
    L = np.where(np.isfinite(L), L, np.inf).reshape(n, nc)
    best = np.argsort(L[:, 1:], axis=1)[:, :options.n_starts] + 1
    log(f"global: {nc} Sobol candidates per material on {target.cells.index.size} cells; "
        f"local searches from the defaults and the best {options.n_starts}")
    return [(i, cand[j]) for i in range(n) for j in [0] + list(best[i])], nc


def global_search(objective: Objective, target: Target, *, names: list[str], options: FitOptions,
                  penalty: bool = True, log: Callable[[str], None] = _quiet) -> StageResult:
    """Local optima of every material of ``target`` (usually the coarse set): one row per local
    search (x, its loss on ``target``), several per material.  ``penalty``: include the
    objective's penalties (brdfcl.optim.objective on why one may leave them out here)."""
    n = len(names)
    nfev = np.zeros(n, dtype=int)
    if options.global_method == "none":
        return StageResult(objective.spaces.default_x(n), np.full(n, np.inf), np.arange(n), nfev,
                           [Status.START] * n, np.ones(n, dtype=bool), "no global search", notes=["defaults"] * n)
    if options.global_method == "lds":
        starts, n_candidates = _lds_starts(objective, target, n, options, penalty, log)
        nfev += n_candidates
    else:
        x_def = objective.spaces.default_x(n)
        starts = [(i, x_def[i]) for i in range(n)]
    lo, hi = objective.spaces.x_bounds
    k = objective.model.n_free
    problems = [Problem(_optimiser(options.global_method, k, lo, hi, options.local_maxeval), x0,
                        material_seed(options.seed, names[i])) for i, x0 in starts]
    mats = np.array([i for i, _ in starts])
    out = run_lockstep(problems, _Batched(objective, target, mats, penalty))
    np.add.at(nfev, mats, [oc.nfev for oc in out])
    return StageResult(np.array([oc.x for oc in out]), np.array([oc.f for oc in out]), mats, nfev,
                       [Status.START] * len(out), np.array([oc.status > 0 for oc in out]),
                       f"{options.global_method}: {len(out)} local searches", notes=[oc.message for oc in out])


def pick_starts(objective: Objective, target: Target, found: StageResult, *, n_materials: int,
                keep: int = 3) -> StageResult:
    """The best row of ``found`` per material judged on ``target`` (usually the full table: the
    coarse loss only ranks, and the ``keep`` best per material are evaluated); the defaults where
    none is finite.  One row per material, with its loss on ``target`` (inf: defaults taken)."""
    x = objective.spaces.default_x(n_materials)
    rows: list[int] = []
    xs: list[np.ndarray] = []
    for i in dict.fromkeys(found.mat.tolist()):            # materials in order of appearance
        mine = np.flatnonzero(found.mat == i)
        for j in mine[np.argsort(found.fun[mine], kind="stable")][:keep]:
            rows.append(i)
            xs.append(found.x[j])
    L = objective.loss(target, np.array(xs), np.array(rows))
    best = np.full(n_materials, np.inf)
    for i, xi, li in zip(rows, xs, L):
        if np.isfinite(li) and li < best[i]:
            best[i], x[i] = li, xi
    nfev = np.bincount(np.array(rows, dtype=int), minlength=n_materials)
    notes = ["best start" if np.isfinite(b) else "defaults (no finite start)" for b in best]
    return StageResult(x, best, np.arange(n_materials), nfev, [Status.START] * n_materials, np.isfinite(best),
                       f"best of {keep} starts per material on {target.cells.index.size} cells", notes=notes)
