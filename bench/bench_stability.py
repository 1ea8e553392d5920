#!/usr/bin/env python3
"""Numerical stability on stiff and extreme cases (run by bench_fit.py --stability, or alone).

* Evaluations: the kernels at the corners of the parameter box, alpha at 1e-4, a at both
  bounds and zero amplitudes, with grazing cells included, on proxy and synthetic extreme
  materials: non-finite values counted, float32 against float64 (worst relative difference).
* Fits: a mirror at alpha = 1e-4 (the lower bound), alpha = 1e-3, near-black and near-white
  materials, proxy materials with grazing cells included, each in float32 and float64:
  failed fits and non-finite results counted, final errors compared.

    python bench/bench_stability.py [--data DIR]
"""
from __future__ import annotations

import argparse
import datetime
import sys
import tempfile
from pathlib import Path

import numpy as np

from brdfcl.data.geometry import table_geometry
from brdfcl.data.merl import read_merl, write_merl
from brdfcl.device.engine import Engine, select_cells
from brdfcl.model.compose import DEFAULT_MODEL, Model
from brdfcl.model.synth import demo_values, tabulate
from brdfcl.optim.fit import FitOptions, Fitter

HERE = Path(__file__).resolve().parent
PROXY = ["chrome", "specular-black-phenolic", "aluminium", "white-diffuse-bball", "black-soft-plastic"]


def extreme_tables(tmp):
    """Synthetic stiff cases as MERL files: {name: path}."""
    g = table_geometry()
    cases = {
        "mirror-alpha-1e-4": ("diffuse+ggx:smith:schlick", {"diffuse.rho": (0.01,) * 3, "ct.rho": (0.9,) * 3,
                                                            "ct.alpha": 1e-4, "ct.F0": (0.9,) * 3}),
        "mirror-alpha-1e-3": ("diffuse+diffraction+ggx", {"diffuse.rho": (0.01,) * 3, "ct.rho": (0.9,) * 3,
                                                          "diffraction.rho": (0.02,) * 3, "ct.alpha": 1e-3}),
    }
    out = {}
    for name, (spec, params) in cases.items():
        m = Model(spec)
        write_merl(Path(tmp) / f"{name}.binary", tabulate(m, demo_values(m, params)))
        out[name] = Path(tmp) / f"{name}.binary"
    for name, level in (("near-black", 1e-6), ("near-white", 0.99 / np.pi)):
        write_merl(Path(tmp) / f"{name}.binary", np.where(g.above_horizon, level, np.nan)[None].repeat(3, 0))
        out[name] = Path(tmp) / f"{name}.binary"
    return out


def corner_values(model, rng, n_random=24):
    lo, hi, d = model.lo, model.hi, model.defaults()
    V = [lo, hi, d]
    V += list(np.where(rng.random((n_random, model.n_params)) < 0.5, lo, hi))
    z = d.copy()
    z[model.amplitude] = 0.0
    V.append(z)
    for name in ("ct.alpha", "diffraction.a"):
        if name in model.names:
            for b in (lo, hi):
                v = d.copy()
                v[model.names.index(name)] = b[model.names.index(name)]
                V.append(v)
    return np.array(V)


def evaluation_checks(tables, spec):
    rng = np.random.default_rng(0)
    idx = select_cells(None)                               # grazing cells included
    e32, e64 = Engine(spec, real="float"), Engine(spec, real="double")
    cs32, cs64 = e32.cellset(tables, idx), e64.cellset(tables, idx)
    V = corner_values(e32.model, rng)
    n_bad, worst_l, worst_g, evals = 0, 0.0, 0.0, 0
    for mat in range(len(tables)):
        mats = np.full(len(V), mat)
        L32, G32 = e32.grad(cs32, V, mats)
        L64, G64 = e64.grad(cs64, V, mats)
        _, r32, H32 = e32.jtj(cs32, V, mats)
        n_bad += int((~np.isfinite(L32)).sum() + (~np.isfinite(G32)).sum() + (~np.isfinite(H32)).sum()
                     + (~np.isfinite(L64)).sum() + (~np.isfinite(G64)).sum())
        ok = np.isfinite(L64) & (L64 > 1e-12)
        if ok.any():
            worst_l = max(worst_l, float(np.max(np.abs(L32[ok] / L64[ok] - 1))))
        gs = np.abs(G64).max(axis=1, keepdims=True)
        big = np.abs(G64) > 1e-3 * gs
        if big.any():
            worst_g = max(worst_g, float(np.max(np.abs(G32 - G64)[big] / np.abs(G64)[big])))
        evals += len(V)
    return {"evaluations": evals, "nonfinite": n_bad, "worst_loss_rel": worst_l, "worst_grad_rel": worst_g}


def fit_checks(paths, spec, cutoff):
    rows = []
    res = {}
    for real in ("float", "double"):
        f = Fitter(FitOptions(model=spec, real=real, cutoff_deg=cutoff))
        res[real] = {r.name: r for r in f.fit([read_merl(p) for p in paths])}
    for name in res["float"]:
        a, b = res["float"][name], res["double"][name]
        finite = all(np.isfinite(v) for r in (a, b) for v in list(r.params.values()) + list(r.errors.values()))
        rows.append({"material": name, "cutoff": cutoff, "ok32": a.success, "ok64": b.success, "finite": finite,
                     "rmse_log32": a.errors["rmse_log"], "rmse_log64": b.errors["rmse_log"],
                     "status32": a.status, "status64": b.status})
    return rows


def stability_report(data, out, model=DEFAULT_MODEL):
    data, out = Path(data), Path(out)
    with tempfile.TemporaryDirectory() as tmp:
        ext = extreme_tables(tmp)
        proxy = [data / f"{n}.binary" for n in PROXY if (data / f"{n}.binary").exists()]
        tables = [read_merl(p) for p in proxy + list(ext.values())]
        ev = {spec: evaluation_checks(tables, spec) for spec in
              (model, "diffuse+diffraction:abc:conductor+beckmann:smith-hc:dielectric", "diffraction:gauss+sgd",
               "diffuse+epd:vcavity:schlick")}
        fits = fit_checks(list(ext.values()), model, 80.0) + fit_checks(proxy, model, None)
    n_fail = sum(not (r["ok32"] and r["ok64"] and r["finite"]) for r in fits)
    n_nonfinite = sum(e["nonfinite"] for e in ev.values()) + sum(not r["finite"] for r in fits)
    lines = [f"# Numerical stability ({datetime.date.today()})", "",
             f"Materials: MERL-proxy {', '.join(p.stem for p in proxy)}; synthetic {', '.join(ext)}.",
             f"**{n_nonfinite} non-finite values, {n_fail} failed fits.**", "",
             "Kernel evaluations at the corners of the parameter box (and alpha at 1e-4, a at both bounds, "
             "zero amplitudes), grazing cells included (no angle cut-off), float32 against float64:", "",
             "| model | evaluations | non-finite | worst loss rel. diff "
             "| worst gradient rel. diff (entries > 1e-3 of max) |",
             "|---|---|---|---|---|"]
    for spec, e in ev.items():
        lines.append(f"| `{spec}` | {e['evaluations']} | {e['nonfinite']} | {e['worst_loss_rel']:.2e} | "
                     f"{e['worst_grad_rel']:.2e} |")
    lines += ["", f"Fits of `{Model(model).spec}` in float32 and float64 (synthetic: 80 deg cut-off; proxy: "
              "grazing cells included):", "",
              "| material | cut-off | rmse_log f32 | rmse_log f64 | status f32 | status f64 | finite |",
              "|---|---|---|---|---|---|---|"]
    for r in fits:
        lines.append(f"| {r['material']} | {r['cutoff'] or 'none'} | {r['rmse_log32']:.4g} | {r['rmse_log64']:.4g} | "
                     f"{r['status32']} | {r['status64']} | {r['finite']} |")
    text = "\n".join(lines)
    (out / "stability.md").write_text(text + "\n")
    print(text)
    return n_nonfinite, n_fail


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=str(Path.home() / ".cache" / "brdfcl" / "proxy-all"))
    ap.add_argument("--out", default=str(HERE / "results"))
    args = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    from bench_eval import proxy_dir
    n_bad, n_fail = stability_report(proxy_dir(args.data), args.out)
    return 1 if n_bad or n_fail else 0


if __name__ == "__main__":
    sys.exit(main())
