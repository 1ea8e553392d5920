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


def write_summary(out_dir: str | Path, cache: dict | None = None, rows: dict | None = None) -> Path:
    """summary.csv from every NAME.json in out_dir; returns its path.  ``cache``: see read_results;
    ``rows``: a dict kept between calls, each document's cells made once (a folder rewritten after
    every fit of a batch would otherwise format every row again each time)."""
    docs = read_results(out_dir, cache)
    rows = {} if rows is None else rows
    pnames: list[str] = []
    for d in docs:
        pnames += [k for k in d["params"] if k not in pnames]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(SUMMARY_COLUMNS + OPTION_COLUMNS + pnames)
    kept = {}
    for d in docs:
        made = rows.get(id(d))
        if made is None or made[0] is not d:
            made = (d, *_cells(d))
        kept[id(d)] = made
        w.writerow(made[1] + [made[2].get(k, "") for k in pnames])
    rows.clear()
    rows.update(kept)                   # the documents of this folder now (the objects held: ids stay theirs)
    path = Path(out_dir) / "summary.csv"
    atomic_write_text(path, buf.getvalue())
    return path


def _cells(d: dict) -> tuple[list, dict]:
    """A document's row: its fixed and option cells, and {parameter: cell}."""
    e = d["errors"]
    row = [d["material"], d["model"], d["metric"], f"{d['seconds']:.3f}", d["evaluations"],
           f"{e['rmse_log']:.6g}", f"{e['rmse_l2']:.6g}", f"{e['rmse_cbrt']:.6g}",
           f"{e['rel_rmse']:.6g}", d.get("message", d["status"])]
    return row + _option_cells(d), {k: f"{v['value']:.8g}" for k, v in d["params"].items()}


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
        # per job's folder: the NAME.json files already read (read_results) and their rows (write_summary)
        self._kept: dict[str, tuple[dict, dict]] = {}

    def applies_to(self, job: Job) -> bool:
        return job.kind == FIT

    def write(self, job: Job, item: Item) -> None:
        write_summary(job.out, *self._kept.setdefault(str(job.out), ({}, {})))

    def finish(self, job: Job, items: list[Item]) -> Path:
        return write_summary(job.out, *self._kept.pop(str(job.out), (None, None)))
