"""What a fit result records, and how a re-run finds out whether it is finished.

NAME.json (written by brdfcl.report.writers.result_json) is ``result_document``: the model,
the parameters with units and bounds, the errors, timings and, under ``options``, the options
that made it (``recorded_options``: every FitOptions field but those that do not change a
result, plus the run's lobe selection, export flag and brdfcl version); summary.csv shows an id
of them (``options_id``) and the main ones.  Resuming (``resume_state``): a material whose
NAME.json holds a successful fit made with the same options is finished and is skipped; a
result made with other options (or with none recorded, by an older brdfcl) is reported, so
that a run never mixes or silently keeps results of other options.  ``export_fit`` tabulates
a fitted model as a MERL table.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from brdfcl._version import __version__
from brdfcl.data.merl import write_merl
from brdfcl.model.compose import Model

# FitOptions fields that do not change a result (same fits, to rounding, whatever their value):
# left out of the record, so that changing them never makes a finished result look different.
# Every other field is recorded and compared, so a new option is covered without listing it.
NOT_RESULT_OPTIONS = frozenset({"device", "vector_width"})
# Recorded but not compared on resume: exporting does not change the fit (a missing export of a
# finished fit is written on resume without refitting).
NOT_COMPARED = frozenset({"export"})


def _jsonable(v):
    return v.item() if hasattr(v, "item") else str(v)


def recorded_options(opts: Any, select_lobes: bool = False, free_peak: bool = False) -> dict:
    """The options that make a result, as NAME.json records them (JSON types): every field of
    ``opts`` (a FitOptions) but NOT_RESULT_OPTIONS, the model as its canonical spec, whether the
    lobes were selected (--select-lobes; --free-peak counts only there) and the brdfcl version.
    The job runner (brdfcl.app.runner) adds ``export``."""
    d = {k: v for k, v in asdict(opts).items() if k not in NOT_RESULT_OPTIONS}
    # model, metric and lobe selection first: a resume names the first option that differs
    d.pop("model")
    d = {"model": Model(opts.model).spec, "metric": d.pop("metric"), "select_lobes": bool(select_lobes),
         "free_peak": bool(select_lobes and free_peak), **d, "brdfcl_version": __version__}
    return json.loads(json.dumps(d, default=_jsonable))


def compared_options(options: dict) -> dict:
    """The recorded options a resume compares (all but NOT_COMPARED)."""
    return {k: v for k, v in options.items() if k not in NOT_COMPARED}


def options_id(options: Any) -> str:
    """Short id of the compared options: equal ids, same options (summary.csv column ``options``)."""
    if not isinstance(options, dict):
        return ""
    text = json.dumps(compared_options(options), sort_keys=True, separators=(",", ":"))
    return hashlib.sha1(text.encode()).hexdigest()[:10]


_ABSENT = object()


def option_difference(recorded: dict, current: dict, prefix: str = "") -> tuple[str, Any, Any] | None:
    """First compared option that differs, as (dotted name, recorded value, current value), values
    _ABSENT where one side lacks it; None when every compared option matches."""
    for k in list(current) + [k for k in recorded if k not in current]:
        if not prefix and k in NOT_COMPARED:
            continue
        a, b = recorded.get(k, _ABSENT), current.get(k, _ABSENT)
        if isinstance(a, dict) and isinstance(b, dict):
            sub = option_difference(a, b, f"{prefix}{k}.")
            if sub:
                return sub
        elif a != b:
            return f"{prefix}{k}", a, b
    return None


def result_document(res: Any, model: Model, extra: dict | None = None, options: dict | None = None) -> dict:
    """What NAME.json holds: model, status (brdfcl.optim.status code) and message, parameters with
    units and bounds, errors, timings, version,
    "uncertainty", "albedo" and "flags" (brdfcl.optim.uncertainty; null / [] when not assessed) and,
    under "options", the options that made it (recorded_options)."""
    params = {}
    for s in model.slots:
        params[s.name] = {"value": res.params[s.name], "unit": s.param.unit, "lo": s.param.lo,
                          "hi": s.param.hi, "log_space": s.param.log, "fixed": s.name in model.fixed}
    doc = {"material": res.name, "model": res.model, "metric": res.metric, "success": res.success,
           "status": int(res.status), "message": res.message, "params": params, "bounds_hit": res.bounds_hit,
           "errors": res.errors,
           "loss": res.loss, "seconds": res.seconds, "evaluations": res.nfev, "stages": res.stages,
           "history": [{"seconds": t, "stage": s, "rmse": e} for t, s, e in res.history],
           "wavelengths_um": list(model.lambdas), "brdfcl_version": __version__}
    # the assessment (brdfcl.optim.assessment): standard errors and correlation, directional albedo, flags
    doc["uncertainty"] = getattr(res, "uncertainty", None)
    doc["albedo"] = getattr(res, "albedo", None)
    doc["flags"] = list(getattr(res, "flags", None) or [])
    # ---
    if options is not None:
        doc["options"] = options
    doc.update(extra or {})
    return doc


def read_results(out_dir: str | Path, cache: dict | None = None) -> list[dict]:
    """Every readable NAME.json in out_dir (other JSON files are ignored).  ``cache``: a dict kept
    between calls; a file whose size, modification time and inode are unchanged is not read again
    (a folder rewritten after every fit would otherwise be re-read whole each time)."""
    docs = []
    for p in sorted(Path(out_dir).glob("*.json")):
        try:
            st = p.stat()
            key = (st.st_size, st.st_mtime_ns, st.st_ino)
            if cache is not None and p in cache and cache[p][0] == key:
                d = cache[p][1]
            else:
                d = json.loads(p.read_text())
                if cache is not None:
                    cache[p] = (key, d)
        except (OSError, ValueError):
            continue
        if isinstance(d, dict) and "material" in d and "params" in d:
            docs.append(d)
    return docs


def resume_state(out_dir: str | Path, name: str, options: dict) -> tuple[str, Any]:
    """How a re-run with ``options`` (recorded_options) treats NAME.json in out_dir:
    ("new", None): no readable result; ("done", doc): a successful fit made with these options;
    ("refit", doc): an unsuccessful one; ("differs", (option, recorded, current)): made with other
    options (option None: no options recorded, an older brdfcl)."""
    p = Path(out_dir) / f"{name}.json"
    try:
        d = json.loads(p.read_text())
    except (OSError, ValueError):
        return "new", None
    if not isinstance(d, dict) or "params" not in d:
        return "new", None
    recorded = d.get("options")
    if not isinstance(recorded, dict):
        return "differs", (None, None, None)
    diff = option_difference(recorded, options)
    if diff:
        return "differs", diff
    return ("done" if d.get("success") else "refit"), d


def is_finished(out_dir: str | Path, name: str, options: dict) -> bool:
    """True if NAME.json holds a successful fit made with these options (recorded_options)."""
    return resume_state(out_dir, name, options)[0] == "done"


def export_fit(path: str | Path, engine: Any, params: dict) -> None:
    """Write a fitted model (params by name) as a MERL table over the whole table."""
    write_merl(path, engine.tabulate(np.array([params[n] for n in engine.model.names])))
