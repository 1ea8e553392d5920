"""Where the time of the default job goes: the stage table of `brdfcl fit-all DB --out OUT`.

Each run is a fresh process started as a user starts the command (default options, the report
included, the output folder removed first), instrumented from inside: the clock starts before the
interpreter does (the parent's time of the spawn).  Stages: the interpreter and brdfcl's imports;
start-up up to the first kernel launch (a self-test); building the engines (code generation,
program build or its kept binary, self-test); reading and extracting the tables; uploading them;
per form, the global and local searches; the assessment of the chosen fits; the report pages;
what is left (choosing forms, writing NAME.json and summary.csv, exit).  Inside the search stages
it splits the time spent waiting for kernels (brdfcl.device.engine.Engine._run: launch and wait
for the results) from the host's own work (nlopt, the lockstep coordination, host constants,
numpy).  Writes bench/results/stages.md.

    python bench/bench_stages.py [--data ~/.cache/brdfcl/proxy-all] [--repeat 3]

The first run of a machine builds and generates what later runs find kept; the table is the
median of ``--repeat`` runs after one unrecorded warm-up (a second process, as a user's every
run after the first).  The machine may be shared: read shares, not absolute seconds.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def cpu_name() -> str:
    """The CPU's model name (Linux), else what platform says."""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def child(spawned: float, out_json: str, argv: list[str]) -> None:
    """One instrumented `brdfcl fit-all` in this process; the stage seconds to ``out_json``."""
    t_main = time.time()
    clock: dict[str, float] = {}
    marks: dict[str, float] = {}

    def add(name, seconds):
        clock[name] = clock.get(name, 0.0) + seconds

    def timed(owner, attr, name, before=None):
        orig = getattr(owner, attr)

        def wrapper(*a, **k):
            if before:
                before()
            t = time.perf_counter()
            try:
                return orig(*a, **k)
            finally:
                add(name, time.perf_counter() - t)
        setattr(owner, attr, wrapper)

    import brdfcl  # noqa: F401
    from brdfcl.app import runner
    from brdfcl.app.cli import main
    from brdfcl.device import engine as engine_mod
    from brdfcl.optim import fit as fit_mod
    from brdfcl.optim import forms as forms_mod
    t_imported = time.time()

    def first_launch():
        marks.setdefault("first launch", time.time())
    timed(engine_mod.Engine, "_run", "kernels", before=first_launch)
    timed(engine_mod.Engine, "__init__", "engines (generation, build, self-test)")
    timed(fit_mod.Fitter, "load", "read + upload")
    timed(forms_mod, "assess", "assessment of the chosen fits")
    timed(runner.Runner, "finish", "report pages and summary")
    timed(fit_mod, "global_search", "global search")
    timed(fit_mod.Fitter, "begin", "fits")          # Fitter.run and the choice of forms call both
    timed(fit_mod.Fitter, "complete", "fits")
    main(argv)
    end = time.time()
    clock["local search"] = clock.pop("fits", 0.0) - clock.get("global search", 0.0)
    if os.environ.get("BRDFCL_STAGES_PRINT"):
        print(json.dumps(clock), file=sys.stderr)
    stages = {"interpreter start": t_main - spawned, "imports": t_imported - t_main,
              "start-up to the first kernel launch": marks.get("first launch", end) - spawned, **clock,
              "total (whole process)": end - spawned}
    Path(out_json).write_text(json.dumps(stages))


def one_run(data: str) -> dict:
    """A whole `fit-all` of ``data`` in a fresh process: its stage seconds."""
    out = Path(tempfile.mkdtemp(prefix="brdfcl-stages-"))
    try:
        js = out / "stages.json"
        spawned = time.time()
        subprocess.run([sys.executable, __file__, "--child", str(spawned), str(js), "fit-all", data, "--out",
                        str(out / "run")], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return json.loads(js.read_text())
    finally:
        shutil.rmtree(out, ignore_errors=True)


def device_name() -> str:
    """The device a default fit runs on, with its OpenCL platform."""
    from brdfcl.device.buildcheck import label
    from brdfcl.device.platforms import pick_device
    p, d = pick_device(None)
    return f"{d.name.strip()} ({label(p)}, driver {d.driver_version.strip()})"


ORDER = ("interpreter start", "imports", "start-up to the first kernel launch",
         "engines (generation, build, self-test)",
         "read + upload", "global search", "local search", "assessment of the chosen fits",
         "report pages and summary", "kernels", "total (whole process)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=str(Path.home() / ".cache" / "brdfcl" / "proxy-all"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=str(HERE / "results" / "stages.md"))
    a = ap.parse_args()
    from brdfcl.data.merl import list_database
    n = len(list_database(a.data))
    one_run(a.data)                                  # warm-up: builds, generation, caches
    runs = []
    for i in range(a.repeat):
        runs.append(one_run(a.data))
        print(f"run {i + 1}: total {runs[-1]['total (whole process)']:.1f} s", flush=True)
    med = {k: statistics.median(r.get(k, 0.0) for r in runs) for k in ORDER}
    total = med["total (whole process)"]
    search = med["global search"] + med["local search"]
    lines = [f"# Stages of the default job: `brdfcl fit-all DB --out OUT` ({n} materials, report included)", "",
             f"Data: {a.data} (MERL-proxy). Default options (the default's choice of forms, the report), "
             f"device: {device_name()}. CPU: {cpu_name()}, {os.cpu_count()} cores. Each run a fresh process "
             f"(its output folder new), timed from its spawn; median of {a.repeat} runs after one warm-up run "
             "(every run after a machine's first finds the generated code, program binaries and report arrays "
             "kept).", "",
             "| stage | s (median) | share of the whole process |", "|---|---|---|"]
    for k in ORDER:
        lines.append(f"| {k} | {med[k]:.2f} | {med[k] / total * 100:.0f}% |")
    lines.append(f"| rest (choosing forms, NAME.json and summary.csv, exit) | "
                 f"{total - sum(med[k] for k in ORDER[:2] + ORDER[3:9]):.2f} | |")
    lines += ["", "'start-up to the first kernel launch' overlaps the rows below it (the first launch is the "
              "first engine's self-test). 'global search' and 'local search' hold every form's ('local': the rest of "
              "each form's fit: picking starts, Levenberg-Marquardt, its errors); 'kernels' is "
              "the wall time inside the engine's launches over the whole run "
              f"({med['kernels'] / max(search, 1e-9) * 100:.0f}% "
              "of the two search rows' sum, which also hold the host's work: nlopt, the lockstep, host constants). "
              "'report pages and summary' is the writers' finish: the report's images and pages.", "",
              "Runs (s): " + "; ".join(f"{r['total (whole process)']:.1f}" for r in runs)]
    Path(a.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(float(sys.argv[2]), sys.argv[3], sys.argv[4:])
    else:
        main()
