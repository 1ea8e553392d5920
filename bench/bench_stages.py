"""Where the time of a whole-database fit goes: the stage table of `brdfcl fit-all`.

Runs the fit of every material of a folder in one batch, in this process, as `fit-all` does
(default options), and times: building the engine (program build or cache, vector-width
decision), reading and extracting the tables, uploading them, the global stage, the local
stage (preview and full-table Levenberg-Marquardt) and the assessment.  Inside the search stages
it splits the time spent waiting for kernels (each launch's blocking read of its results,
wrapped around brdfcl.device.engine.Engine._run) from the host's own work (nlopt, the lockstep
coordination, numpy).  Writes bench/results/stages.md.

    python bench/bench_stages.py [--data ~/.cache/brdfcl/proxy-all] [--repeat 3]

The machine may be shared: the table gives the median of ``--repeat`` runs of each figure.
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

from brdfcl.data.inputs import FileReader
from brdfcl.data.merl import list_database
from brdfcl.device import engine as engine_mod
from brdfcl.optim.fit import FitOptions, Fitter, load_batch

HERE = Path(__file__).resolve().parent


class KernelClock:
    """Wall time spent inside Engine._run (launch + wait for the results), by kernel."""

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._orig = engine_mod.Engine._run

    def __enter__(self):
        clock = self

        def timed(eng, kname, cs, values, mats):
            t = time.perf_counter()
            try:
                return clock._orig(eng, kname, cs, values, mats)
            finally:
                clock.seconds[kname] = clock.seconds.get(kname, 0.0) + time.perf_counter() - t
                clock.calls[kname] = clock.calls.get(kname, 0) + 1
        engine_mod.Engine._run = timed
        return self

    def __exit__(self, *exc):
        engine_mod.Engine._run = self._orig

    def total(self) -> float:
        return sum(self.seconds.values())


def cpu_name() -> str:
    """The CPU's model name (Linux), else what platform says."""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def one_run(paths) -> dict:
    """Seconds per stage of one whole fit."""
    out = {}
    t0 = time.perf_counter()
    fitter = Fitter(FitOptions())
    out["engine (build, width)"] = time.perf_counter() - t0
    t = time.perf_counter()
    names, full, coarse = load_batch([FileReader(p) for p in paths], fitter)
    out["read + extract"] = time.perf_counter() - t
    t = time.perf_counter()
    targets = fitter.targets(names, full, coarse)
    out["upload + targets"] = time.perf_counter() - t
    with KernelClock() as clock:
        t = time.perf_counter()
        res = fitter.run(list(names), targets, full, t)
        end = time.perf_counter()
        t_global = res[0].stages["global"]
    assess = res[0].stages.get("uncertainty", 0.0)
    t_local = end - t - t_global - assess
    k_all = clock.total()
    out["global"] = t_global
    out["local (preview + full LM)"] = t_local
    out["assessment"] = assess
    out["kernels, all search stages"] = k_all
    out["host, all search stages"] = (end - t) - k_all
    out["total"] = time.perf_counter() - t0
    out["_evals"] = float(np.mean([r.nfev for r in res]))
    out["_launches"] = dict(clock.calls)
    return out


def device_name(selector: str | None = None) -> str:
    """The device ``selector`` picks (None: the one a default fit runs on, BRDFCL_DEVICE honoured),
    with its OpenCL platform."""
    from brdfcl.device.buildcheck import label
    from brdfcl.device.platforms import pick_device
    p, d = pick_device(selector)
    return f"{d.name.strip()} ({label(p)}, driver {d.driver_version.strip()})"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=str(Path.home() / ".cache" / "brdfcl" / "proxy-all"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=str(HERE / "results" / "stages.md"))
    a = ap.parse_args()
    paths = list_database(a.data)
    runs = []
    for i in range(a.repeat):
        r = one_run(paths)
        runs.append(r)
        print(f"run {i + 1}: total {r['total']:.1f} s", flush=True)
    keys = [k for k in runs[0] if not k.startswith("_")]
    med = {k: statistics.median(r[k] for r in runs) for k in keys}
    lines = [f"# Stages of a whole-database fit ({len(paths)} materials, one batch)", "",
             f"Data: {a.data} (MERL-proxy). Default options, device: {device_name()}. "
             f"CPU: {cpu_name()}, {os.cpu_count()} cores; "
             f"median of {a.repeat} runs in one process (the first builds or reads the program cache). "
             f"Mean evaluations per material: {runs[-1]['_evals']:.0f}; launches per run: {runs[-1]['_launches']}.",
             "", "| stage | s (median) | share of total |", "|---|---|---|"]
    for k in keys:
        if k.startswith("engine"):      # built once per process: the first run's figure
            lines.append(f"| {k}, first run | {runs[0][k]:.2f} | {runs[0][k] / runs[0]['total'] * 100:.0f}% |")
            continue
        lines.append(f"| {k} | {med[k]:.2f} | {med[k] / med['total'] * 100:.0f}% |")
    lines += ["", "Rows 'kernels' and 'host' split the global, local and assessment stages together: "
              "'kernels' is the wall time inside the engine's launches (launch and wait for results), "
              "'host' everything else in those stages (nlopt, lockstep coordination, numpy)."]
    Path(a.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
