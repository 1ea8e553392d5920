"""The calibration study's files in its output folder: ``cases.csv`` (one row per analysed case
and table kind) and ``timing.json`` (seconds per stage).

The rows are appended chunk by chunk, so a study that stops keeps what it analysed and a rerun
resumes from it; the times add up over the runs that made the rows.
"""
from __future__ import annotations

import csv
import json
import os


def read_rows(path) -> list[dict]:
    """The rows of a cases file, as strings ([] when there is none)."""
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def append_rows(path, rows) -> None:
    """Append rows to a cases file (its header written when the file is new)."""
    if not rows:
        return
    new = not os.path.exists(path)
    with open(path, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        if new:
            w.writeheader()
        w.writerows(rows)


def add_timing(path, timing) -> dict:
    """Seconds per stage, summed over the runs that made cases.csv (a resumed study adds up)."""
    old = json.loads(path.read_text()) if path.exists() else {}
    new = {k: old.get(k, 0.0) + v for k, v in timing.items()}
    path.write_text(json.dumps(new, indent=1))
    return new


def read_timing(path) -> dict | None:
    """The seconds per stage a study kept, None when it kept none."""
    return json.loads(path.read_text()) if path.exists() else None
