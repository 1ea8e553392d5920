"""summary.csv: one row per NAME.json in the output folder, finished now or in an earlier run.

Fixed columns (SUMMARY_COLUMNS), then the options that made each fit (OPTION_COLUMNS: the id of
all recorded options, brdfcl.report.output.options_id, then the main ones), then every parameter
by name.  It is rewritten from the folder after each fit, so that it is current whenever a run
stops, and once more at the end (a run that only resumed writes it too).
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

from brdfcl.report.files import atomic_write_text
from brdfcl.report.output import options_id, read_results
from brdfcl.report.writers.base import FIT, Item, Job, Writer

SUMMARY_COLUMNS = ["material", "model", "metric", "seconds", "evaluations", "rmse_log", "rmse_l2",
                   "rmse_cbrt", "rel_rmse", "status"]
# after the fixed columns: the id of all recorded options (equal ids, same options), then the main ones
OPTION_COLUMNS = ["options", "real", "cutoff_deg", "fixed", "seed", "ct_peak", "global_method",
                  "select_lobes", "brdfcl_version"]


def write_summary(out_dir: str | Path, cache: dict | None = None) -> Path:
    """summary.csv from every NAME.json in out_dir; returns its path.  ``cache``: see read_results."""
    docs = read_results(out_dir, cache)
    pnames: list[str] = []
    for d in docs:
        pnames += [k for k in d["params"] if k not in pnames]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(SUMMARY_COLUMNS + OPTION_COLUMNS + pnames)
    for d in docs:
        e = d["errors"]
        row = [d["material"], d["model"], d["metric"], f"{d['seconds']:.3f}", d["evaluations"],
               f"{e['rmse_log']:.6g}", f"{e['rmse_l2']:.6g}", f"{e['rmse_cbrt']:.6g}",
               f"{e['rel_rmse']:.6g}", d.get("message", d["status"])]
        row += _option_cells(d)
        row += [f"{d['params'][k]['value']:.8g}" if k in d["params"] else "" for k in pnames]
        w.writerow(row)
    path = Path(out_dir) / "summary.csv"
    atomic_write_text(path, buf.getvalue())
    return path


def _option_cells(doc: dict) -> list[str]:
    o = doc.get("options")
    if not isinstance(o, dict):                 # an older brdfcl recorded no options
        return [""] * (len(OPTION_COLUMNS) - 1) + [doc.get("brdfcl_version", "")]

    def cell(v):
        if isinstance(v, dict):
            return ";".join(f"{k}={v[k]:g}" if isinstance(v[k], float) else f"{k}={v[k]}" for k in sorted(v))
        return "none" if v is None else str(v).lower() if isinstance(v, bool) else str(v)
    return [options_id(o)] + [cell(o.get(k, "")) for k in OPTION_COLUMNS[1:]]


class SummaryCsv(Writer):
    """summary.csv of a fit job; it reads the NAME.json files, so it runs after ResultJson."""

    name = "summary"

    def __init__(self) -> None:
        self._read: dict[str, dict] = {}   # per job's folder: NAME.json files already read (read_results)

    def applies_to(self, job: Job) -> bool:
        return job.kind == FIT

    def write(self, job: Job, item: Item) -> None:
        write_summary(job.out, self._read.setdefault(str(job.out), {}))

    def finish(self, job: Job, items: list[Item]) -> Path:
        return write_summary(job.out, self._read.pop(str(job.out), None))
