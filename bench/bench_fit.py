#!/usr/bin/env python3
"""Error against run time: brdfcl against what users would write instead, in one process.

On a set of MERL-proxy materials (default: a dozen spanning metals, paints, plastics,
fabrics and woods; --all for every one), the same model, metric and cells are fitted by
* brdfcl at several settings (global search budget, float32/float64, coarse subset size),
  all materials of the set in one batch;
* scipy.optimize.least_squares (trf, analytic Jacobian from the float64 reference, log-space
  parameters with the same bounds, started from the model defaults), one material at a time;
* PyTorch on the CPU (autograd, Adam then L-BFGS, float32), if torch is installed
  (pip install -e ".[torch]"), on the first --torch-materials materials.
Errors are sampled during each run.  Outputs in --out: fit_curves.csv (method, setting,
material, seconds, rmse_log, rmse_l2, rmse_cbrt), fit_vs_time.png and bench_fit.md (time to
reach the scipy fit's and the PyTorch fit's final errors, speed-ups, the whole database on each
--devices PoCL against the peers extrapolated).  --published instead compares brdfcl's fits of
every material with the published fits of bench/published.py (bench/compare_published.py).

    python bench/bench_fit.py [--data DIR] [--all] [--stability] [--devices 'pocl 3.0']
    python bench/bench_fit.py --published [--published-models MODEL,MODEL]
"""
from __future__ import annotations

import argparse
import csv
import datetime
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdfcl import __version__
from brdfcl.data.geometry import DEFAULT_CUTOFF_DEG, table_geometry
from brdfcl.data.merl import read_merl
from brdfcl.device.cellsets import select_cells
from brdfcl.model.compose import DEFAULT_MODEL, Model
from brdfcl.model.metrics import errors, transform
from brdfcl.optim.fit import FitOptions, Fitter

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_eval import proxy_dir  # noqa: E402

HERE = Path(__file__).resolve().parent
DEFAULT_SET = ["aluminium", "brass", "chrome", "steel", "gold-metallic-paint", "blue-metallic-paint",
               "white-paint", "specular-red-phenolic", "gray-plastic", "blue-fabric", "pink-fabric",
               "cherry-235"]
SETTINGS = {
    "default": {},
    "float64": {"real": "double"},
    "no-global": {"global_method": "none"},
    "budget-x4": {"n_candidates": 1024, "n_starts": 8},
    "coarse-x2": {"coarse_stride": 48, "coarse_peak_stride": 3},
}


class Recorder:
    """Samples (seconds, errors) of one run; 'best so far' curves are derived when reporting."""

    def __init__(self, method, setting, material, t0):
        self.key, self.t0, self.rows = (method, setting, material), t0, []

    def add(self, err, t=None):
        t = time.perf_counter() - self.t0 if t is None else t
        self.rows.append((t, err.get("rmse_log", np.nan), err.get("rmse_l2", np.nan), err.get("rmse_cbrt", np.nan)))


def run_brdfcl(paths, setting, kw, model, metric):
    f = Fitter(FitOptions(model=model, metric=metric, **kw))
    loaded = f.load([read_merl(p) for p in paths])
    t0 = time.perf_counter()
    res = f.fit_loaded(loaded)
    total = time.perf_counter() - t0
    recs = []
    for r in res:
        rec = Recorder("brdfcl", setting, r.name, 0)
        for t, _, rmse in r.history:
            rec.add({f"rmse_{metric}": rmse}, t)
        rec.add(r.errors, r.seconds)
        recs.append(rec)
    return recs, total


def scipy_problem(model, table, idx, metric, dtype=np.float64):
    from brdfcl.model.lobes.cells import Cells
    g = table_geometry()
    cells = Cells.from_geometry(g, idx).astype(dtype)
    m = table.brdf()[:, idx].astype(dtype)
    w = g.weight[idx].astype(dtype)
    ok = np.isfinite(m)
    cw = cells.ci
    sw = np.sqrt(np.where(ok, w, 0))
    target = transform(metric, np.where(ok, m, 0) * cw)[0]
    return cells, m, w, ok, cw, sw, target


def run_scipy(path, model, metric, idx, max_nfev=200):
    from scipy.optimize import least_squares
    table = read_merl(path)
    cells, m, w, ok, cw, sw, target = scipy_problem(model, table, idx, metric)
    rec = Recorder("scipy", "trf", table.name, time.perf_counter())
    total_w = 3 * np.sum(w)

    def fun(x):
        v = model.from_x(x)
        p = model.reference(cells, v, jacobian=False)
        r = (sw * np.where(ok, transform(metric, p * cw)[0] - target, 0)).ravel()
        err = errors(p, m, w, cw) if len(rec.rows) % 5 == 0 else {f"rmse_{metric}": np.sqrt(r @ r / total_w)}
        rec.add(err)
        return r

    def jac(x):
        v = model.from_x(x)
        p, J = model.reference(cells, v)
        d = transform(metric, p * cw)[1] * cw * sw
        Jx = (d[..., None] * J * model.dvalue_dx(v)).reshape(-1, model.n_free)
        return Jx

    x0 = model.to_x(model.defaults())
    sol = least_squares(fun, x0, jac=jac, bounds=(model.x_lo, model.x_hi), method="trf", x_scale="jac",
                        ftol=1e-8, xtol=1e-10, gtol=1e-10, max_nfev=max_nfev)
    p = model.reference(cells, model.from_x(sol.x), jacobian=False)
    rec.add(errors(p, m, w, cw))
    return rec


def run_torch(path, model_spec, metric, idx, adam_steps=150, lbfgs_iter=40):
    """Diffuse + diffraction (hp) + GGX/Smith/Schlick in PyTorch, autograd, float32."""
    import torch
    torch.set_num_threads(2)
    model = Model(model_spec)
    if model.spec != "diffuse+diffraction:hp:none+ggx:smith:schlick":
        raise ValueError("the PyTorch peer implements the default three-lobe model only")
    table = read_merl(path)
    cells, m, w, ok, cw, sw, target = scipy_problem(model, table, idx, metric, np.float32)
    T = {k: torch.from_numpy(np.ascontiguousarray(v)) for k, v in dict(
        sh=cells.sh, ch=cells.ch, cd=cells.cd, ci=cells.ci, co=cells.co, w=np.where(ok, w, 0).astype(np.float32),
        target=target.astype(np.float32), ok=ok).items()}
    lam = torch.tensor(model.lambdas, dtype=torch.float32)[:, None]
    lo, hi = torch.tensor(model.x_lo), torch.tensor(model.x_hi)
    x = torch.tensor(model.to_x(model.defaults()), dtype=torch.float32, requires_grad=True)
    logs = torch.tensor(model.log[model.free_index])
    names = [model.names[i] for i in model.free_index]
    rec = Recorder("pytorch", "adam+lbfgs", table.name, time.perf_counter())
    t2 = (T["sh"] / T["ch"]) ** 2
    t2i, t2o = (1 - T["ci"] ** 2) / T["ci"] ** 2, (1 - T["co"] ** 2) / T["co"] ** 2
    s5 = (1 - T["cd"]) ** 5

    def predict(xx):
        xx = torch.minimum(torch.maximum(xx, lo.float()), hi.float())
        v = torch.where(logs, torch.exp(xx), xx)
        P = dict(zip(names, v))
        rho = lambda lb: torch.stack([P[f"{lb}.rho_{c}"] for c in "rgb"])[:, None]  # noqa: E731
        a2 = P["ct.alpha"] ** 2
        D = a2 / (np.pi * T["ch"] ** 4 * (a2 + t2) ** 2)
        lam_i = lambda tt: (torch.sqrt(1 + a2 * tt) - 1) / 2  # noqa: E731
        G = 1 / ((1 + lam_i(t2i)) * (1 + lam_i(t2o)))
        F0 = torch.stack([P[f"ct.F0_{c}"] for c in "rgb"])[:, None]
        F = F0 + (1 - F0) * s5
        ct = rho("ct") * D * G * F / (4 * T["ci"] * T["co"])
        f = 2 * T["sh"] * T["cd"] / lam
        S = 1 / (1 + (f / P["diffraction.a"]) ** 2) ** 2
        dr = rho("diffraction") / lam ** 4 * S
        return rho("diffuse") / np.pi + dr + ct

    def loss_fn():
        p = predict(x)
        r = torch.where(T["ok"], torch.log1p(p * T["ci"]) - T["target"], torch.zeros(()))
        return (T["w"] * r * r).sum()

    def sample():
        with torch.no_grad():
            p = predict(x).double().numpy()
        rec.add(errors(p, m, w, cw))

    opt = torch.optim.Adam([x], lr=0.05)
    for step in range(adam_steps):
        opt.zero_grad()
        loss = loss_fn()
        loss.backward()
        opt.step()
        if step % 10 == 0:
            sample()
    opt = torch.optim.LBFGS([x], lr=1, max_iter=lbfgs_iter, history_size=20, line_search_fn="strong_wolfe")

    def closure():
        opt.zero_grad()
        loss = loss_fn()
        loss.backward()
        return loss
    opt.step(closure)
    sample()
    return rec


def load_curves(path):
    recs = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            key = (row["method"], row["setting"], row["material"])
            rec = recs.setdefault(key, Recorder(*key, 0))
            rec.rows.append(tuple(float(row[k]) for k in ("seconds", "rmse_log", "rmse_l2", "rmse_cbrt")))
    return list(recs.values())


def best_curve(rec, col=1):
    t = np.array([r[0] for r in rec.rows])
    e = np.array([r[col] for r in rec.rows])
    keep = np.isfinite(e)
    return t[keep], np.minimum.accumulate(e[keep])


def time_to(rec, target):
    t, e = best_curve(rec)
    hit = np.flatnonzero(e <= target)
    return float(t[hit[0]]) if hit.size else np.nan


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=str(Path.home() / ".cache" / "brdfcl" / "proxy-all"))
    ap.add_argument("--all", action="store_true", help="every material of --data")
    ap.add_argument("--materials", default=None, help="comma-separated names (default: a dozen)")
    ap.add_argument("--model", default=DEFAULT_MODEL)
    ap.add_argument("--metric", default="log")
    ap.add_argument("--settings", default=",".join(SETTINGS))
    ap.add_argument("--scipy-materials", type=int, default=None, help="scipy on the first N only")
    ap.add_argument("--torch-materials", type=int, default=3)
    ap.add_argument("--database-seconds", type=float, default=None,
                    help="measured whole-database brdfcl fit time to put beside the extrapolation "
                         "(default: measure it now with fit-all on --data)")
    ap.add_argument("--devices", default="",
                    help="comma-separated device selectors (as --device of brdfcl, e.g. 'pocl 3.0'): brdfcl's "
                         "default setting and the whole-database time are measured on each as well")
    ap.add_argument("--database-runs", type=int, default=3, help="whole-database fits per device (median)")
    ap.add_argument("--published", action="store_true",
                    help="instead: brdfcl's fits against the published fits (bench/published.py) on every material "
                         "of --data "
                         "(bench/compare_published.py; writes published.md and published.csv)")
    ap.add_argument("--published-models", default=f"default,{DEFAULT_MODEL}",
                    help="brdfcl models compared with --published (comma-separated; the first is the one ranked; "
                         "'default': what fit-all fits when no model is given, each material's form chosen)")
    ap.add_argument("--stability", action="store_true", help="also run the numerical stability report")
    ap.add_argument("--scipy-only", metavar="MATERIAL", default=None,
                    help="only the scipy peer on this one material of --data, as a whole process (a user's script)")
    ap.add_argument("--report-only", action="store_true",
                    help="rebuild bench_fit.md and the plot from --out/fit_curves.csv without fitting")
    ap.add_argument("--out", default=str(HERE / "results"))
    args = ap.parse_args(argv)

    data = proxy_dir(args.data)
    all_paths = sorted(data.glob("*.binary"))
    if args.all:
        paths = all_paths
    else:
        names = args.materials.split(",") if args.materials else DEFAULT_SET
        paths = [data / f"{n}.binary" for n in names if (data / f"{n}.binary").exists()]
    if args.scipy_only:
        rec = run_scipy(data / f"{args.scipy_only}.binary", Model(args.model), args.metric,
                        select_cells(DEFAULT_CUTOFF_DEG))
        print(f"scipy {args.scipy_only}: rmse_{args.metric} {rec.rows[-1][1]:.5f} after {rec.rows[-1][0]:.1f} s, "
              f"{len(rec.rows) - 1} evaluations")
        return
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.published:
        from compare_published import compare
        from compare_published import report as published_report
        print(published_report(out) if args.report_only else
              compare(paths if args.materials else all_paths, args.published_models.split(","), out,
                      f"MERL-proxy ({data})"))
        return 0
    if args.report_only:
        recs = load_curves(out / "fit_curves.csv")
        names = sorted({r.key[2] for r in recs if r.key[0] == "brdfcl"})
        batch = {r.key[1]: 0.0 for r in recs if r.key[0] == "brdfcl"}
        for r in recs:
            if r.key[0] == "brdfcl":
                batch[r.key[1]] = max(batch[r.key[1]], r.rows[-1][0])
        report(recs, batch, [data / f"{n}.binary" for n in names], all_paths, args, out)
        return 0
    model = Model(args.model)
    idx = Fitter(FitOptions(model=args.model)).full_index
    recs, batch_seconds = [], {}
    for s in args.settings.split(","):
        r, total = run_brdfcl(paths, s, SETTINGS[s], args.model, args.metric)
        recs += r
        batch_seconds[s] = total
        print(f"brdfcl {s}: {len(paths)} materials in {total:.1f} s", flush=True)
    for dev in filter(None, args.devices.split(",")):
        r, total = run_brdfcl(paths, f"default@{dev}", {"device": dev}, args.model, args.metric)
        recs += r
        batch_seconds[f"default@{dev}"] = total
        print(f"brdfcl default on '{dev}': {len(paths)} materials in {total:.1f} s", flush=True)
    for p in paths[:args.scipy_materials]:
        recs.append(run_scipy(p, model, args.metric, idx))
        print(f"scipy {p.stem}: {recs[-1].rows[-1][0]:.1f} s", flush=True)
    try:
        import torch  # noqa: F401
        have_torch = True
    except ImportError:
        have_torch = False
        print("PyTorch peer skipped: torch is not installed (pip install -e '.[torch]')")
    if have_torch:
        for p in paths[:args.torch_materials]:
            recs.append(run_torch(p, args.model, args.metric, idx))
            print(f"pytorch {p.stem}: {recs[-1].rows[-1][0]:.1f} s", flush=True)

    with open(out / "fit_curves.csv", "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["method", "setting", "material", "seconds", "rmse_log", "rmse_l2", "rmse_cbrt"])
        for rec in recs:
            for row in rec.rows:
                wr.writerow(list(rec.key) + [f"{v:.6g}" for v in row])

    report(recs, batch_seconds, paths, all_paths, args, out)
    if args.stability:
        from bench_stability import stability_report
        stability_report(data, out)
    return 0


def database_seconds(all_paths, args, devices):
    """Median wall time of `brdfcl fit-all`'s fit of every file (reading included) in --model, the
    peers' model (forms=None: not the default's choice of forms), per device (None: the default
    device), keyed by the device's description."""
    from bench_stages import device_name

    from brdfcl.app.run import fit_all
    out = {}
    for dev in devices:
        name = device_name(dev)
        times = []
        for _ in range(args.database_runs):
            t = time.perf_counter()
            fit_all(all_paths, None, FitOptions(model=args.model, metric=args.metric, device=dev), forms=None)
            times.append(time.perf_counter() - t)
        out[name] = float(np.median(times))
        print(f"whole database on {name}: {out[name]:.1f} s (runs {', '.join(f'{x:.1f}' for x in times)})", flush=True)
    return out


@dataclass
class Reach:
    """How one method's runs reach a rival's final errors, on the materials both ran."""

    times: list          # per material that reached it: seconds until it did
    speedups: list       # the rival's own time to that error over this method's
    final_ratio: list    # per material in common: this method's final rmse_log over the rival's

    def __bool__(self) -> bool:
        return bool(self.final_ratio)

    def __str__(self) -> str:
        """The table cells: materials reaching it, median time, median speed-up."""
        med = lambda v: np.median(v) if v else float("nan")  # noqa: E731
        return f"{len(self.times)}/{len(self.final_ratio)} | {med(self.times):.2f} | {med(self.speedups):.1f}x"


def reaching(runs: dict, rival: dict) -> Reach:
    """When each run of ``runs`` (material -> Recorder) reached the final rmse_log of ``rival``'s run
    of the same material (within 0.1%)."""
    out = Reach([], [], [])
    for name, r in runs.items():
        if name not in rival:
            continue
        target = rival[name].rows[-1][1] * (1 + 1e-3)
        t_m = time_to(r, target)
        out.final_ratio.append(r.rows[-1][1] / rival[name].rows[-1][1])
        if np.isfinite(t_m):
            out.times.append(t_m)
            out.speedups.append(time_to(rival[name], target) / t_m)
    return out


def report(recs, batch_seconds, paths, all_paths, args, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    by = {}
    for r in recs:
        by.setdefault(r.key[:2], {})[r.key[2]] = r
    scipy = by.get(("scipy", "trf"), {})
    torch_recs = by.get(("pytorch", "adam+lbfgs"), {})
    fig, ax = plt.subplots(figsize=(8, 5))
    lines = [f"# bench_fit: error against run time ({datetime.date.today()})", "",
             f"Data: MERL-proxy, {len(paths)} materials ({', '.join(p.stem for p in paths)}). Model "
             f"`{Model(args.model).spec}`, metric `{args.metric}`, 80 degree cut-off, same cells for "
             f"every method. brdfcl {__version__}, one process, 2-core machine. brdfcl fits the set "
             "as one batch: its per-material time is the wall time of the whole batch until that "
             "material reached the error (launches are shared), so it is a conservative figure.", ""]
    # whole-set curves: mean over the materials every method ran of the best-so-far rmse_log at each time
    common = set.intersection(*(set(d) for d in by.values())) if by else set()
    for (method, setting), d in sorted(by.items()):
        grid = np.geomspace(0.05, max(max(r.rows[-1][0] for r in d.values()), 0.1), 200)
        curves = []
        for r in (d[k] for k in sorted(common)):
            t, e = best_curve(r)
            curves.append(np.interp(grid, t, e, left=np.nan) if t.size else np.full(grid.size, np.nan))
        curves = np.array(curves)
        started = np.isfinite(curves).all(axis=0)          # once every material has a sample
        ax.plot(grid[started], curves[:, started].mean(axis=0), "-" if method == "brdfcl" else "--",
                label=f"{method} {setting}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel(f"rmse_{args.metric}, best so far, mean over materials")
    ax.legend(fontsize=8)
    ax.set_title(f"error against run time (MERL-proxy; mean over the {len(common)} materials every method ran)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "fit_vs_time.png", dpi=100)
    plt.close(fig)

    if scipy:
        lines += ["Time to reach the scipy fit's final rmse_log (per material; median over materials), and the "
                  "speed-up against scipy's own time to that error:", "",
                  "| method | setting | materials reaching it | median time (s) | median speed-up vs scipy | "
                  "final rmse_log / scipy's (median) |", "|---|---|---|---|---|---|"]
        for (method, setting), d in sorted(by.items()):
            reach = reaching(d, scipy)
            if reach:
                lines.append(f"| {method} | {setting} | {reach} | {np.median(reach.final_ratio):.3f} |")
        lines += ["", "Whole set: time until every material has reached the scipy fit's final rmse_log "
                  "(brdfcl: one batch, so the latest material; scipy and PyTorch: one material after "
                  "another, so the sum):", "",
                  "| method | setting | all reached | time for the set (s) | speed-up vs scipy |",
                  "|---|---|---|---|---|"]
        t_sc = sum(time_to(r, r.rows[-1][1] * (1 + 1e-3)) for r in scipy.values())
        for (method, setting), d in sorted(by.items()):
            tt = [time_to(r, scipy[nm].rows[-1][1] * (1 + 1e-3)) for nm, r in d.items() if nm in scipy]
            if len(tt) != len(scipy):
                continue
            reached = all(np.isfinite(tt))
            t_set = (max(tt) if method == "brdfcl" else sum(tt)) if reached else float("nan")
            lines.append(f"| {method} | {setting} | {'yes' if reached else 'no'} | {t_set:.1f} | "
                         f"{t_sc / t_set:.0f}x |" if reached else
                         f"| {method} | {setting} | no ({sum(np.isfinite(tt))}/{len(tt)}) | - | - |")
        n_s = len(scipy)
        t_scipy = sum(r.rows[-1][0] for r in scipy.values())
        per = t_scipy / n_s
        lines += ["", f"Whole set: scipy {t_scipy:.0f} s for {n_s} materials ({per:.1f} s each, one at a "
                  f"time); brdfcl default {batch_seconds.get('default', float('nan')):.1f} s for "
                  f"{len(paths)} materials in one batch."]
        per_db = {"given by --database-seconds": args.database_seconds} if args.database_seconds else {}
        if not per_db and not args.report_only:
            per_db = database_seconds(all_paths, args, [None] + list(filter(None, args.devices.split(","))))
        if per_db:
            t_torch = [r.rows[-1][0] for r in torch_recs.values()]
            runs = "as given" if args.database_seconds else f"median of {args.database_runs} runs in this process"
            lines += ["", f"Whole database ({len(all_paths)} materials), `brdfcl` default options, reading the "
                      f"files included, {runs}, against the peers' "
                      "per-material times extrapolated (one material after another):", "",
                      "| device | brdfcl (s) | scipy, extrapolated (s) | speed-up vs scipy | PyTorch, extrapolated (s) "
                      "| speed-up vs PyTorch |", "|---|---|---|---|---|---|"]
            for dev, db in per_db.items():
                tt = np.mean(t_torch) * len(all_paths) if t_torch else None
                torch_cells = f"{tt:.0f} | {tt / db:.0f}x" if tt else "not run | -"
                lines.append(f"| {dev} | {db:.1f} | {per * len(all_paths):.0f} | {per * len(all_paths) / db:.0f}x | "
                             f"{torch_cells} |")
            if t_torch:
                lines.append(f"\nPyTorch's time is its whole run (Adam then L-BFGS) on {len(t_torch)} materials; "
                             "it does not reach scipy's error on every one (table above).")
    if torch_recs:
        lines += ["", "Time to reach the PyTorch fit's final rmse_log (on the materials PyTorch ran; its own time to "
                  "that error against each method's):", "",
                  "| method | setting | materials reaching it | median time (s) | median speed-up vs PyTorch |",
                  "|---|---|---|---|---|"]
        for (method, setting), d in sorted(by.items()):
            reach = reaching(d, torch_recs)
            if reach:
                lines.append(f"| {method} | {setting} | {reach} |")
    lines += ["", "![error against time](fit_vs_time.png)", "",
              "Curves and samples: `fit_curves.csv` (method, setting, material, seconds, rmse_log, rmse_l2, "
              "rmse_cbrt; brdfcl samples carry the fit metric during the run and all three at the end)."]
    text = "\n".join(lines)
    (out / "bench_fit.md").write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    sys.exit(main())
