"""Published fits a report compares each material with: their scores from a CSV file.

brdfcl carries no published fit (their files belong to their authors); a user who has them scores
them on the same tables and cells as brdfcl's fits (``bench/bench_fit.py --published`` does so for
BBM's fit files) and hands the result to ``fit-all --published FILE``.  The file has a header row
with at least ``material``, ``best_published`` (the published fit's name) and
``best_published_rmse_log`` (its rmse_log, brdfcl.model.metrics, on that material's table); other
columns are ignored.  The report then names, per material, that fit and the ratio of brdfcl's
rmse_log to it.
"""
from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass


class PublishedError(ValueError):
    """A scores file that cannot be used; the message is one line naming the file."""


COLUMNS = ("material", "best_published", "best_published_rmse_log")


@dataclass(frozen=True)
class Published:
    """The best published fit of a material: its name and its rmse_log on the material's table."""

    fit: str
    rmse_log: float

    def ratio(self, rmse_log) -> float | None:
        """brdfcl's ``rmse_log`` over the published one's (below 1: brdfcl's fit is closer)."""
        if not isinstance(rmse_log, (int, float)) or not math.isfinite(rmse_log):
            return None
        return float(rmse_log) / self.rmse_log


def read_published(path) -> dict[str, Published]:
    """{material: Published} from a scores CSV (see the module's docstring); PublishedError, one
    line naming the file, for a file that cannot be read, lacks a column, or has a row whose score is
    not a positive finite number or whose material appears twice."""
    path = os.fspath(path)
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            rows = list(reader)
            header = reader.fieldnames or []
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        why = e.strerror if isinstance(e, OSError) and e.strerror else \
            (str(e).splitlines() or [type(e).__name__])[0][:120]
        raise PublishedError(f"{path}: cannot read the published scores: {why}") from e
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise PublishedError(f"{path}: published scores need the columns {', '.join(COLUMNS)}; "
                             f"missing: {', '.join(missing)}")
    out: dict[str, Published] = {}
    for line, row in enumerate(rows, start=2):
        name, fit, text = ((row.get(c) or "").strip() for c in COLUMNS)
        if not name:
            raise PublishedError(f"{path}: line {line}: no material")
        try:
            score = float(text)
        except ValueError:
            score = math.nan
        if not (math.isfinite(score) and score > 0):
            raise PublishedError(f"{path}: line {line}: best_published_rmse_log '{text[:40]}' of {name[:60]} "
                                 "is not a positive number")
        if name in out:
            raise PublishedError(f"{path}: line {line}: {name[:60]} appears twice")
        out[name] = Published(fit or "(unnamed)", score)
    return out
