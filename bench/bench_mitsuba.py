#!/usr/bin/env python3
"""Render time of a fitted material in Mitsuba 3: the generated Dr.Jit BSDF against the numpy one.

The numpy plugin is the one brdfcl shipped before the Dr.Jit BSDF (one numpy call per ray,
scalar_rgb only), taken from git (``--old-rev``) and run in its own process.  Every
configuration renders the same scene, the one ``brdfcl export --mitsuba`` writes
(NAME-scene.xml: a sphere under a key light and a dim sky, path tracing to depth 3, BSDF
sampling included), in a fresh process, round-robin, ``--repeat`` times; the figure is the
median.  The numpy plugin is too slow for the full image (about 2 ms a sample): it renders a
smaller one and its time per sample is compared, which the table says.

    python bench/bench_mitsuba.py [--fits DIR] [--repeat 3] [--out bench/results/mitsuba_render.md]

Without ``--fits`` it fits the demo database first, with default options (``brdfcl fit-all
--demo --no-report``), and renders its default-fit plastic and metal.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
MATERIALS = ("synth-smooth-plastic", "synth-smooth-metal")

RENDER = r"""
import json, sys, time
t0 = time.perf_counter()
import mitsuba as mi
variant, plugin, scene_file, res, spp, old_rev = sys.argv[1:7]
mi.set_variant(variant)
if plugin == "numpy":
    import subprocess, types
    src = subprocess.run(["git", "show", f"{old_rev}:brdfcl/report/export/mitsuba.py"], capture_output=True,
                         text=True, check=True, cwd=sys.argv[7]).stdout
    mod = types.ModuleType("brdfcl_numpy_plugin")
    exec(compile(src, "brdfcl_numpy_plugin", "exec"), mod.__dict__)
else:
    import brdfcl.report.export.mitsuba  # noqa: F401
scene = mi.load_file(scene_file, res=int(res), spp=int(spp))
t1 = time.perf_counter()
img = mi.render(scene)
import numpy as np
mean = float(np.array(img).mean())
t2 = time.perf_counter()
print(json.dumps({"render_s": t2 - t1, "process_s": t2 - t0, "mean": mean}))
"""

CONFIGS = [  # (label, variant, plugin, res, spp)
    ("numpy plugin, scalar_rgb", "scalar_rgb", "numpy", 32, 4),
    ("Dr.Jit BSDF, scalar_rgb", "scalar_rgb", "drjit", 64, 16),
    ("Dr.Jit BSDF, llvm_ad_rgb", "llvm_ad_rgb", "drjit", 256, 64),
]


def fit_demo(out: Path) -> Path:
    subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "fit-all", "--demo", "--out", str(out), "--no-report"],
                   check=True, stdout=subprocess.DEVNULL)
    return out


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fits", type=Path, help="a fit-all output folder (default: fit the demo database)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--old-rev", default="e3c3330", help="the git revision of the numpy plugin")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "mitsuba_render.md")
    args = ap.parse_args(argv)
    repo = HERE.parent
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        fits = args.fits or fit_demo(tmp / "fits")
        scenes = {}
        for name in MATERIALS:
            subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "export", str(fits / f"{name}.json"),
                            "--mitsuba", str(tmp / "mitsuba")], check=True, stdout=subprocess.DEVNULL)
            scenes[name] = tmp / "mitsuba" / f"{name}-scene.xml"
        times: dict = {}
        for r in range(args.repeat):
            for name, scene in scenes.items():
                for label, variant, plugin, res, spp in CONFIGS:
                    run = subprocess.run([sys.executable, "-c", RENDER, variant, plugin, str(scene), str(res), str(spp),
                                          args.old_rev, str(repo)], capture_output=True, text=True, cwd=scene.parent)
                    if run.returncode != 0:
                        sys.exit(f"{label} on {name} failed: {run.stderr.strip().splitlines()[-1]}")
                    doc = json.loads(run.stdout.strip().splitlines()[-1])
                    times.setdefault((name, label), []).append(doc)
                    print(f"run {r + 1}: {name:22s} {label:28s} {res}x{res} {spp:3d} spp: "
                          f"render {doc['render_s']:8.2f} s, process {doc['process_s']:8.2f} s", flush=True)
    lines = ["# Mitsuba 3 render time of a fitted material: the Dr.Jit BSDF and the numpy plugin", "",
             f"{datetime.date.today()}, {cpu_name()}, {os.cpu_count()} cores; data: `synthetic` (the demo "
             f"database, default fit-all options); the scene `brdfcl export --mitsuba` writes (NAME-scene.xml: "
             f"path tracing to depth 3, a key light and a sky, BSDF and light sampling); each configuration in "
             f"a fresh process, round-robin, median of {args.repeat}.  The numpy plugin is the one of git "
             f"{args.old_rev}.", "",
             "| material | configuration | image | render s | process s | ns per sample | "
             "vs numpy plugin, per sample |", "|---|---|---|---|---|---|---|"]
    for name in MATERIALS:
        base = None
        for label, _, _, res, spp in CONFIGS:
            docs = times[(name, label)]
            rs = statistics.median(d["render_s"] for d in docs)
            ps = statistics.median(d["process_s"] for d in docs)
            per = rs / (res * res * spp) * 1e9
            base = base or per
            lines.append(f"| {name} | {label} | {res}x{res}, {spp} spp | {rs:.2f} | {ps:.2f} | {per:,.0f} | "
                         f"{base / per:,.0f}x |")
    big = [(res, spp) for _, _, _, res, spp in CONFIGS][-1]
    lines += ["", f"For the {big[0]}x{big[0]}, {big[1]} spp image, the numpy plugin would take its time per sample "
                  f"times {big[0] * big[0] * big[1]:,} samples (its image here is smaller: rendering the full one "
                  f"takes hours)."]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
