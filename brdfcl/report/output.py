"""Fit outputs: NAME.json per material, summary.csv, exported MERL tables; all written atomically.

Every NAME.json records the options that made it (``recorded_options``: every FitOptions
field but those that do not change a result, plus the run's lobe selection, export flag and
brdfcl version); summary.csv shows an id of them and the main ones.  Resuming
(``resume_state``): a material whose NAME.json holds a successful fit made with the same
options is finished and is skipped; a result made with other options (or with none recorded,
by an older brdfcl) is reported, so that a run never mixes or silently keeps results of
other options.
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import re
from dataclasses import asdict
from pathlib import Path

import numpy as np

from brdfcl._version import __version__
from brdfcl.data.merl import write_merl
from brdfcl.model.compose import Model

SUMMARY_COLUMNS = ["material", "model", "metric", "seconds", "evaluations", "rmse_log", "rmse_l2",
                   "rmse_cbrt", "rel_rmse", "status"]
# after the fixed columns: the id of all recorded options (equal ids, same options), then the main ones
OPTION_COLUMNS = ["options", "real", "cutoff_deg", "fixed", "seed", "ct_peak", "global_method",
                  "select_lobes", "brdfcl_version"]

# FitOptions fields that do not change a result (same fits, to rounding, whatever their value):
# left out of the record, so that changing them never makes a finished result look different.
# Every other field is recorded and compared, so a new option is covered without listing it.
NOT_RESULT_OPTIONS = frozenset({"device", "vector_width"})
# Recorded but not compared on resume: exporting does not change the fit (a missing export of a
# finished fit is written on resume without refitting).
NOT_COMPARED = frozenset({"export"})


def _jsonable(v):
    return v.item() if hasattr(v, "item") else str(v)


def recorded_options(opts, select_lobes=False, free_peak=False) -> dict:
    """The options that make a result, as NAME.json records them (JSON types): every field of
    ``opts`` (a FitOptions) but NOT_RESULT_OPTIONS, the model as its canonical spec, whether the
    lobes were selected (--select-lobes; --free-peak counts only there) and the brdfcl version.
    result_writer adds ``export``."""
    d = {k: v for k, v in asdict(opts).items() if k not in NOT_RESULT_OPTIONS}
    # model, metric and lobe selection first: a resume names the first option that differs
    d.pop("model")
    d = {"model": Model(opts.model).spec, "metric": d.pop("metric"), "select_lobes": bool(select_lobes),
         "free_peak": bool(select_lobes and free_peak), **d, "brdfcl_version": __version__}
    return json.loads(json.dumps(d, default=_jsonable))


def compared_options(options: dict) -> dict:
    return {k: v for k, v in options.items() if k not in NOT_COMPARED}


def options_id(options) -> str:
    """Short id of the compared options: equal ids, same options (summary.csv column ``options``)."""
    if not isinstance(options, dict):
        return ""
    text = json.dumps(compared_options(options), sort_keys=True, separators=(",", ":"))
    return hashlib.sha1(text.encode()).hexdigest()[:10]


_ABSENT = object()


def option_difference(recorded: dict, current: dict, prefix=""):
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


def atomic_write_text(path, text):
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)


_TEMPORARY = re.compile(r"\.tmp\d+$|\.tmp\.(exr|png)$")


def remove_stale_temporaries(out_dir):
    """Temporary files left by a run killed mid-write (``*.tmpPID``; final names are never partial)."""
    for p in Path(out_dir).iterdir():
        if p.is_file() and _TEMPORARY.search(p.name):
            try:
                p.unlink()
            except OSError:
                pass


def result_document(res, model: Model, extra=None, options=None) -> dict:
    """What NAME.json holds: model, parameters with units and bounds, errors, timings, version,
    "uncertainty", "albedo" and "flags" (brdfcl.optim.uncertainty; null / [] when not assessed) and,
    under "options", the options that made it (recorded_options)."""
    params = {}
    for s in model.slots:
        params[s.name] = {"value": res.params[s.name], "unit": s.param.unit, "lo": s.param.lo,
                          "hi": s.param.hi, "log_space": s.param.log, "fixed": s.name in model.fixed}
    doc = {"material": res.name, "model": res.model, "metric": res.metric, "success": res.success,
           "status": res.status, "params": params, "bounds_hit": res.bounds_hit, "errors": res.errors,
           "loss": res.loss, "seconds": res.seconds, "evaluations": res.nfev, "stages": res.stages,
           "history": [{"seconds": t, "stage": s, "rmse": e} for t, s, e in res.history],
           "wavelengths_um": list(model.lambdas), "brdfcl_version": __version__}
    # issue 17 (brdfcl.optim.uncertainty): standard errors and correlation, directional albedo, flags
    doc["uncertainty"] = getattr(res, "uncertainty", None)
    doc["albedo"] = getattr(res, "albedo", None)
    doc["flags"] = list(getattr(res, "flags", None) or [])
    # ---
    if options is not None:
        doc["options"] = options
    doc.update(extra or {})
    return doc


def write_result(out_dir, doc):
    atomic_write_text(Path(out_dir) / f"{doc['material']}.json", json.dumps(doc, indent=1))


def read_results(out_dir):
    """Every readable NAME.json in out_dir (other JSON files are ignored)."""
    docs = []
    for p in sorted(Path(out_dir).glob("*.json")):
        try:
            d = json.loads(p.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(d, dict) and "material" in d and "params" in d:
            docs.append(d)
    return docs


def resume_state(out_dir, name, options):
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


def is_finished(out_dir, name, options):
    """True if NAME.json holds a successful fit made with these options (recorded_options)."""
    return resume_state(out_dir, name, options)[0] == "done"


def write_summary(out_dir):
    """summary.csv from every NAME.json in out_dir: fixed columns, the options (OPTION_COLUMNS),
    then every parameter by name."""
    docs = read_results(out_dir)
    pnames = []
    for d in docs:
        pnames += [k for k in d["params"] if k not in pnames]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(SUMMARY_COLUMNS + OPTION_COLUMNS + pnames)
    for d in docs:
        e = d["errors"]
        row = [d["material"], d["model"], d["metric"], f"{d['seconds']:.3f}", d["evaluations"],
               f"{e['rmse_log']:.6g}", f"{e['rmse_l2']:.6g}", f"{e['rmse_cbrt']:.6g}",
               f"{e['rel_rmse']:.6g}", d["status"]]
        row += _option_cells(d)
        row += [f"{d['params'][k]['value']:.8g}" if k in d["params"] else "" for k in pnames]
        w.writerow(row)
    atomic_write_text(Path(out_dir) / "summary.csv", buf.getvalue())


def _option_cells(doc):
    o = doc.get("options")
    if not isinstance(o, dict):                 # an older brdfcl recorded no options
        return [""] * (len(OPTION_COLUMNS) - 1) + [doc.get("brdfcl_version", "")]

    def cell(v):
        if isinstance(v, dict):
            return ";".join(f"{k}={v[k]:g}" if isinstance(v[k], float) else f"{k}={v[k]}" for k in sorted(v))
        return "none" if v is None else str(v).lower() if isinstance(v, bool) else str(v)
    return [options_id(o)] + [cell(o.get(k, "")) for k in OPTION_COLUMNS[1:]]


def export_fit(path, engine, params):
    """Write a fitted model (params by name) as a MERL table over the whole table."""
    write_merl(path, engine.tabulate(np.array([params[n] for n in engine.model.names])))
