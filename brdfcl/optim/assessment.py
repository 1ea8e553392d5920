"""What a finished fit is worth, the pipeline's last stage: its reported errors, the parameters at
a bound, and standard errors (brdfcl.optim.uncertainty), directional albedo
(brdfcl.optim.albedo) and flags for values a user should not trust, in NAME.json's form."""
from __future__ import annotations

import logging
import re
from collections.abc import Sequence

import numpy as np

from brdfcl.model.compose import Model
from brdfcl.optim.albedo import ALBEDO_LIMIT, ALBEDO_THETA_DEG, directional_albedo
from brdfcl.optim.objective import Objective, Target
from brdfcl.optim.result import StageResult
from brdfcl.optim.status import Status
from brdfcl.optim.uncertainty import Uncertainty, json_number, standard_errors

_log = logging.getLogger("brdfcl")

RELATIVE_ERROR_LIMIT = 1.0              # flag a parameter whose standard error exceeds |value|
TRADE_LIMIT = 0.99                      # flag two lobes' amplitudes in one channel correlated beyond this
TRADE_SHARE = 0.05                      # ... where each gives at least this share of the channel's albedo


def evaluate(objective: Objective, target: Target, done: StageResult) -> StageResult:
    """The error evaluation of finished rows on ``target`` (the full table): their reported errors
    (brdfcl.model.metrics), the parameters at a bound, and success: a finite loss and errors (a
    failed row's status says why)."""
    err = objective.engine.errors(target.cells, objective.spaces.values(done.x), done.mat)
    ok = np.array([bool(np.isfinite(done.fun[j]) and all(np.isfinite(e[j]) for e in err.values()))
                   for j in range(done.mat.size)], dtype=bool)
    status = [s if good else Status.FAILED for s, good in zip(done.status, ok)]
    notes = [done.note(j) if good else f"after {done.row_message(j)}" for j, good in enumerate(ok)]
    return StageResult(done.x, done.fun, done.mat, done.nfev, status, ok, "errors evaluated", errors=err,
                       bounds_hit=[bounds_hit(objective.model, x) for x in done.x], notes=notes)


def albedo_json(albedo_row: np.ndarray, theta_i_deg: Sequence[float] = ALBEDO_THETA_DEG) -> dict:
    """One fit's directional albedo (angles, channels) in NAME.json's form."""
    return {"theta_i_deg": [float(t) for t in theta_i_deg],
            "channels": [[json_number(a) for a in row] for row in albedo_row]}


# --- flags ---------------------------------------------------------------------------------------
def flags(model: Model, values: np.ndarray, at_bound: Sequence[str] = (), unc: Uncertainty | None = None,
          albedo_row: np.ndarray | None = None, theta_i_deg: Sequence[float] = ALBEDO_THETA_DEG,
          lobe_albedo: dict | None = None) -> list[str]:
    """One line per reason not to take a fit at face value: energy conservation broken (albedo above
    1 in a channel), parameters at a bound, parameters the data leave undetermined, lobes that trade
    places (``lobe_albedo``: {lobe prefix: (angles, channels)} each lobe's own albedo, see `trades`)."""
    out = []
    if albedo_row is not None:
        a = np.asarray(albedo_row, dtype=np.float64)
        a = np.where(np.isfinite(a), a, np.inf)
        if (a > ALBEDO_LIMIT).any():
            j, c = (int(k) for k in np.unravel_index(np.argmax(a), a.shape))
            angles = [f"{theta_i_deg[t]:g}" for t in range(a.shape[0]) if (a[t] > ALBEDO_LIMIT).any()]
            out.append(f"non-physical: directional albedo above 1 (up to {a[j, c]:.4g} in channel "
                       f"{model.channels[c]} at theta_i {theta_i_deg[j]:g} deg; above 1 at {', '.join(angles)} deg): "
                       f"the fit reflects more energy than it receives")
    v = np.asarray(values, dtype=np.float64)
    for name in at_bound:
        i = model.names.index(name)
        lo, hi = model.lo[i], model.hi[i]
        side = "lower" if abs(v[i] - lo) <= abs(hi - v[i]) else "upper"
        out.append(f"{name} = {v[i]:.4g} at its {side} bound {lo if side == 'lower' else hi:g} "
                   f"(no standard error)")
    if unc is not None:
        for name, s in unc.std_error.items():
            val = v[model.names.index(name)]
            if s is not None and s > RELATIVE_ERROR_LIMIT * abs(val):
                out.append(f"{name} = {val:.4g} poorly determined: standard error {s:.3g} exceeds its value")
        out += trades(model, unc, lobe_albedo)
    return out


def trades(model: Model, unc: Uncertainty, lobe_albedo: dict | None = None) -> list[str]:
    """Lobes that trade places: in some channels the amplitudes of two lobes correlated beyond
    TRADE_LIMIT (in magnitude), so that the data fix what they give together far better than how
    they split it (a broad reflection lobe standing in for the diffuse, a flat diffraction halo for
    either), and, with ``lobe_albedo`` ({prefix: (angles, channels)}), each of the two giving at
    least TRADE_SHARE of their summed albedo at the first angle (a lobe with next to nothing to
    give away changes no value that matters).  One line per pair of lobes, naming the channels and
    the strongest correlation."""
    def shares(la: str, lb: str, c: int) -> bool:
        if lobe_albedo is None or la not in lobe_albedo or lb not in lobe_albedo:
            return True
        a, b = float(lobe_albedo[la][0][c]), float(lobe_albedo[lb][0][c])
        return bool(np.isfinite(a) and np.isfinite(b) and min(a, b) >= TRADE_SHARE * (a + b) > 0)
    slots = {s.name: s for s in model.slots if s.amplitude}
    at = {n: k for k, n in enumerate(unc.names) if n in slots}
    corr = np.asarray(unc.correlation, dtype=np.float64)
    found: dict[tuple[str, str], list[tuple[str, float]]] = {}
    for a, i in at.items():
        for b, j in at.items():
            sa, sb, c = slots[a], slots[b], slots[a].channel
            if (c is not None and sa.lobe < sb.lobe and c == sb.channel and abs(corr[i, j]) > TRADE_LIMIT
                    and shares(sa.lobe, sb.lobe, c)):
                found.setdefault((sa.lobe, sb.lobe), []).append((model.channels[c], float(corr[i, j])))
    out = []
    for (la, lb), chans in found.items():
        worst = max(chans, key=lambda c: abs(c[1]))
        out.append(f"lobes {la} and {lb} {TRADED} in channel{'s' * (len(chans) > 1)} "
                   f"{', '.join(c for c, _ in chans)} (amplitude correlation {worst[1]:+.3f} in {worst[0]}): the data "
                   f"fix their sum there, not how it splits between them")
    return out


TRADED = "trade places"


def traded(flags) -> list[tuple[str, str]]:
    """The pairs of lobes (prefixes) that `trades` names in a fit's ``flags``."""
    found = (re.match(rf"lobes (\S+) and (\S+) {TRADED} ", f) for f in flags)
    return [(m[1], m[2]) for m in found if m]


def bounds_hit(model: Model, x: np.ndarray) -> list[str]:
    """Free parameters at a bound in the optimiser's space x (FitResult.bounds_hit)."""
    return [model.names[k] for k, xx, a, b in zip(model.free_index, x, model.x_lo, model.x_hi)
            if min(xx - a, b - xx) <= 1e-6 * max(1.0, abs(b - a))]


def assess(objective: Objective, target: Target, *, data: np.ndarray, values: np.ndarray, rows: np.ndarray,
           at_bound: list[list[str]]) -> list[dict]:
    """{"uncertainty", "albedo", "flags"} (NAME.json form) for the fits ``values`` (natural) of the
    materials ``rows`` of ``target`` (the full cell set; ``data``: every material's values there),
    ``at_bound`` the names at a bound per fit.  One jtj launch for all of them.  A failure here
    never costs the fits: they get a flag saying why they were not assessed."""
    try:
        return _assess(objective, target, data, values, rows, at_bound)
    except Exception as e:          # noqa: BLE001 - a diagnostic must not lose a finished fit
        _log.warning(f"brdfcl: uncertainty not computed: {type(e).__name__}: {e}")
        return [{"uncertainty": None, "albedo": None,
                 "flags": [f"not assessed: {type(e).__name__}: {e}"]} for _ in rows]


def _assess(objective, target, data, values, rows, at_bound):
    model = objective.model
    values = np.atleast_2d(np.asarray(values, dtype=np.float64))
    rows = np.asarray(rows)
    extra = objective.penalty_hessian(values, target.scale[rows])
    finite = np.isfinite(values).all(axis=1)
    unc = [None] * len(rows)
    if finite.any():
        sel = np.flatnonzero(finite)
        got = standard_errors(objective.engine, target.cells, data, values[sel], rows[sel],
                              at_bound=[at_bound[j] for j in sel], extra_hessian=None if extra is None else extra[sel])
        for j, u in zip(sel, got):
            unc[j] = u
    safe = np.where(finite[:, None], values, model.defaults())
    # each lobe's own albedo, for the fits whose amplitudes correlate enough to trade places only
    traded = [j for j in range(len(rows)) if finite[j] and unc[j] is not None and trades(model, unc[j])]
    lobes = [lb.prefix for lb in model.lobes]
    amp = np.array([s.amplitude for s in model.slots])
    own = [np.where(amp & (np.array([s.lobe for s in model.slots]) != p), 0.0, safe[traded]) for p in lobes]
    every = directional_albedo(model, np.concatenate([safe] + (own if traded else [])), engine=objective.engine)
    alb = every[:len(rows)]
    per_lobe = every[len(rows):].reshape(len(lobes) if traded else 0, len(traded), *alb.shape[1:])
    lobe_albedo = {j: {p: per_lobe[k, c] for k, p in enumerate(lobes)} for c, j in enumerate(traded)}
    out = []
    for j in range(len(rows)):
        if not finite[j]:
            out.append({"uncertainty": None, "albedo": None,
                        "flags": ["not assessed: non-finite parameters"]})
            continue
        out.append({"uncertainty": unc[j].as_json(), "albedo": albedo_json(alb[j]),
                    "flags": flags(model, values[j], at_bound[j], unc[j], alb[j],
                                   lobe_albedo=lobe_albedo.get(j))})
    return out
