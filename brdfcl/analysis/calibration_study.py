"""The calibration study's cases, analysed in chunks so that memory stays bounded
(brdfcl.analysis.calibration for the cases, brdfcl.analysis.nbrdf for the round trip):

1. draw the cases of a Plan, tabulate and "measure" each (noise, grazing noise, missing cells);
2. fit the compared variants and run the tests on every measured table (``original``);
3. send every ``roundtrip_every``-th case through the NBRDF recipe (train a 6-21-21-3 network per
   table, tabulate it as merl_proxy.py does) and analyse the round-tripped table (``roundtrip``);
4. append each analysed case to ``cases.csv`` (brdfcl.analysis.calibration_store), so that a
   rerun resumes from it.

The summary of the rows is brdfcl.analysis.calibration_summary's.
"""
from __future__ import annotations

import time
from pathlib import Path

from brdfcl.analysis import nbrdf
from brdfcl.analysis.calibration import Compared, Plan, analyse_cases, synthesize
from brdfcl.analysis.calibration_store import add_timing, append_rows, read_rows
from brdfcl.optim.fit import FitOptions

DEFAULT_EPOCHS = 20          # the recipe runs 100; bench/results/calibration/epochs.md compares
QUICK_EPOCHS = 2
CHUNK = 12


def run_cases(out: Path, plan: Plan, epochs: int = DEFAULT_EPOCHS, roundtrip: bool = True,
              options: FitOptions | None = None, chunk: int = CHUNK, log=None) -> dict:
    """Analyse the plan's cases not yet in ``out/cases.csv`` into it; returns the seconds per stage,
    summed over the runs that made the file (``out/timing.json``)."""
    log = log or (lambda s: None)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "cases.csv"
    done = {(r["case"], r["table"]) for r in read_rows(path)}
    cases = plan.cases()
    rt_names = {c.name for c in plan.roundtrip(cases)} if roundtrip else set()
    compared = None
    t_start = time.perf_counter()
    timing = {"synthesis": 0.0, "analysis original": 0.0, "nbrdf training": 0.0, "nbrdf tabulation": 0.0,
              "analysis roundtrip": 0.0}
    for s in range(0, len(cases), chunk):
        part = [c for c in cases[s:s + chunk] if (c.name, "original") not in done
                or (c.name in rt_names and (c.name, "roundtrip") not in done)]
        if not part:
            continue
        compared = compared or Compared(options)
        t = time.perf_counter()
        tables = {c.name: synthesize(c)[1] for c in part}
        timing["synthesis"] += time.perf_counter() - t
        todo = [c for c in part if (c.name, "original") not in done]
        t = time.perf_counter()
        rows = analyse_cases(todo, tables, compared, batch=chunk, tag="original")
        timing["analysis original"] += time.perf_counter() - t
        rt = [c for c in part if c.name in rt_names and (c.name, "roundtrip") not in done]
        if rt:
            t = time.perf_counter()
            tr = nbrdf.train([tables[c.name] for c in rt], nbrdf.TrainOptions(epochs=epochs, seed=plan.seed))
            timing["nbrdf training"] += time.perf_counter() - t
            t = time.perf_counter()
            rt_tables = {c.name: nbrdf.tabulate(w) for c, w in zip(rt, tr.weights)}
            timing["nbrdf tabulation"] += time.perf_counter() - t
            del tables
            t = time.perf_counter()
            rt_rows = analyse_cases(rt, rt_tables, compared, batch=chunk, tag="roundtrip")
            timing["analysis roundtrip"] += time.perf_counter() - t
            for r, lt, lv in zip(rt_rows, tr.loss[:, -1], tr.test_loss):
                r["nbrdf_train_loss"], r["nbrdf_test_loss"] = float(lt), float(lv)
            rows += rt_rows
        for r in rows:
            r.setdefault("nbrdf_train_loss", "")
            r.setdefault("nbrdf_test_loss", "")
        append_rows(path, rows)
        log(f"cases {min(s + chunk, len(cases))}/{len(cases)} ({time.perf_counter() - t_start:.0f} s): "
            + ", ".join(f"{r['case']} {r['table'][:4]} {r['verdict']}" for r in rows))
    timing["total"] = time.perf_counter() - t_start
    return add_timing(out / "timing.json", timing)
