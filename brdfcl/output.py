"""Fit outputs: NAME.json per material, summary.csv, exported MERL tables; all written atomically.

Resuming: a material whose NAME.json exists with the same model and metric and a
successful status is finished, and is skipped by a re-run of the same command.
"""
from __future__ import annotations

import csv
import io
import json
import os
import re
from pathlib import Path

import numpy as np

from . import __version__
from .merl import write_merl
from .model import Model

SUMMARY_COLUMNS = ["material", "model", "metric", "seconds", "evaluations", "rmse_log", "rmse_l2",
                   "rmse_cbrt", "rel_rmse", "status"]


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


def result_document(res, model: Model, extra=None) -> dict:
    """What NAME.json holds: model, parameters with units and bounds, errors, timings, version."""
    params = {}
    for s in model.slots:
        params[s.name] = {"value": res.params[s.name], "unit": s.param.unit, "lo": s.param.lo,
                          "hi": s.param.hi, "log_space": s.param.log, "fixed": s.name in model.fixed}
    doc = {"material": res.name, "model": res.model, "metric": res.metric, "success": res.success,
           "status": res.status, "params": params, "bounds_hit": res.bounds_hit, "errors": res.errors,
           "loss": res.loss, "seconds": res.seconds, "evaluations": res.nfev, "stages": res.stages,
           "history": [{"seconds": t, "stage": s, "rmse": e} for t, s, e in res.history],
           "wavelengths_um": list(model.lambdas), "brdfcl_version": __version__}
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


def is_finished(out_dir, name, model_spec, metric, selected=False):
    """True if NAME.json holds a successful fit of this model and metric (with --select-lobes:
    a successful fit whose lobes were selected, whatever they are)."""
    p = Path(out_dir) / f"{name}.json"
    try:
        d = json.loads(p.read_text())
    except (OSError, ValueError):
        return False
    same_model = ("selected_by" in d) if selected else (d.get("model") == model_spec and "selected_by" not in d)
    return bool(d.get("success")) and same_model and d.get("metric") == metric


def write_summary(out_dir):
    """summary.csv from every NAME.json in out_dir: fixed columns, then every parameter by name."""
    docs = read_results(out_dir)
    pnames = []
    for d in docs:
        pnames += [k for k in d["params"] if k not in pnames]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(SUMMARY_COLUMNS + pnames)
    for d in docs:
        e = d["errors"]
        row = [d["material"], d["model"], d["metric"], f"{d['seconds']:.3f}", d["evaluations"],
               f"{e['rmse_log']:.6g}", f"{e['rmse_l2']:.6g}", f"{e['rmse_cbrt']:.6g}",
               f"{e['rel_rmse']:.6g}", d["status"]]
        row += [f"{d['params'][k]['value']:.8g}" if k in d["params"] else "" for k in pnames]
        w.writerow(row)
    atomic_write_text(Path(out_dir) / "summary.csv", buf.getvalue())


def export_fit(path, engine, params):
    """Write a fitted model (params by name) as a MERL table over the whole table."""
    write_merl(path, engine.tabulate(np.array([params[n] for n in engine.model.names])))
