#!/usr/bin/env python3
"""The Smith Lambda of the heavy-tailed distributions (GTR, ABC): the registered shadowing terms
(shadowing/smith_gtr.py, smith_abc.py: a series whose coefficients the host computes from a rule)
against the exact Smith Lambda.

The exact Lambda is computed here from its definition (Heitz 2014, eq. 17 with the projected area
of eq. 9), independently of the rule the terms use:

    Lambda(o) = (1 / cos theta_o) int max(0, -o.m) D(m) dm     (= int max(0, o.m) D dm / cos - 1),

with D the registered distribution's own float64 reference (its host normalisation included), the
phi integral in closed form (int_0^2pi max(0, -(a cos phi + b)) dphi = 2 (sqrt(a^2 - b^2) -
b arccos(b / a)), a = sin theta_o sin theta, b = cos theta_o cos theta, for a > b) and the theta
integral over [90 deg - theta_o, 90 deg] by a Gauss-Legendre rule of N_THETA nodes in v, theta =
90 deg - theta_o + theta_o v^2 (which makes the (theta - theta_c)^(3/2) onset smooth).  The exact
values are checked twice: against the same integral with twice the nodes, and against the
closed-form-cumulative form ((1/pi) int tan^2 b P db, shadowing/smith.py) by adaptive quadrature at
a sample of points.

Reported: the relative error of G1 = 1 / (1 + Lambda) (the masking of one direction), its largest
value over theta_o <= 80 deg (the default angle cut-off of a fit) for each parameter pair, over the
whole parameter box and over the region fits use; the same beyond 80 deg (85, 88, 89.5 deg); and,
for comparison, two cheaper stand-ins for GTR: GGX's Lambda with the same alpha, and with the alpha
that matches Lambda at small theta_o (alpha_eff^2 = s (1 - alpha^2) / (alpha^-2s - 1), s = gamma - 1).

    python bench/lambda_gtr.py            # prints the tables, writes bench/results/lambda_gtr.md
"""
from __future__ import annotations

import argparse
import datetime
import time
from functools import cache
from pathlib import Path

import numpy as np
from scipy import integrate

from brdfcl.model.lobes.cells import Cells
from brdfcl.model.terms import REGISTRY
from brdfcl.model.terms.shadowing.smith import HOST_NODES, SERIES_TERMS

HERE = Path(__file__).resolve().parent
N_THETA = 240
THETA_O = np.arange(1.0, 80.01, 1.0)             # degrees: the validated range
GRAZING = np.array([85.0, 88.0, 89.5])


def _cells(sh, ch, co=None):
    one = np.ones_like(ch)
    return Cells(sh, ch, one, one, one if co is None else co)


def ndf_values(name, theta, params):
    """D(theta) of a registered distribution, float64, host constants included."""
    term = REGISTRY["ndf"][name]
    p = {k: np.float64(v) for k, v in params.items()}
    v, _ = term.reference(_cells(np.sin(theta), np.cos(theta)), **p, **term.consts(**p))
    return v


@cache
def _nodes(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return (x + 1.0) / 2.0, w / 2.0


def exact_lambda(name, params, theta_o_deg, n=N_THETA):
    """The exact Smith Lambda (back-facing projected area / cos theta_o) at each theta_o (degrees)."""
    to = np.radians(np.asarray(theta_o_deg, dtype=np.float64))[:, None]
    v, wv = _nodes(n)
    theta = np.pi / 2 - to + to * v * v
    dtheta = 2.0 * to * v * wv
    a, b = np.sin(to) * np.sin(theta), np.cos(to) * np.cos(theta)
    F = 2.0 * (np.sqrt(np.maximum(a * a - b * b, 0.0)) - b * np.arccos(np.clip(b / a, -1.0, 1.0)))
    D = ndf_values(name, theta.ravel(), params).reshape(theta.shape)
    return np.sum(F * D * np.sin(theta) * dtheta, axis=1) / np.cos(to[:, 0])


def model_g1(shadowing, params, theta_o_deg):
    """G1(theta_o) of a registered separable Smith term: its G with theta_i = 0 (Lambda(0) = 0)."""
    co = np.cos(np.radians(np.asarray(theta_o_deg, dtype=np.float64)))
    term = REGISTRY["shadowing"][shadowing]
    g, _ = term.reference(_cells(np.zeros_like(co), np.ones_like(co), co),
                          **{k: np.float64(v) for k, v in params.items()})
    return g


def share_gtr(t, alpha, gamma):
    """GTR's closed-form share of the projected area beyond tan theta_m = t."""
    s = gamma - 1.0
    r = (alpha ** 2 + t * t) / (1.0 + t * t)
    return np.expm1(-s * np.log(r)) / np.expm1(-2.0 * s * np.log(alpha))


def share_abc(t, B, C):
    """ABC's share beyond tan theta_m = t, by adaptive quadrature of mu (1 + B (1 - mu))^-C."""
    mu = 1.0 / np.sqrt(1.0 + t * t)
    f = lambda m: m * (1.0 + B * (1.0 - m)) ** -C          # noqa: E731
    num = integrate.quad(f, 0.0, mu, epsrel=1e-12, epsabs=0.0, limit=200)[0]
    den = integrate.quad(f, 0.0, 1.0, epsrel=1e-12, epsabs=0.0, limit=200,
                         points=[1.0 - 10.0 / B] if B > 10 else None)[0]
    return num / den


def lambda_by_share(share, tau):
    f = lambda b: np.tan(b) ** 2 * share(1.0 / (tau * np.cos(b)))   # noqa: E731
    return integrate.quad(f, 0.0, np.pi / 2, limit=400, epsrel=1e-11, epsabs=0.0)[0] / np.pi


def ggx_g1(alpha, theta_o_deg):
    u = alpha * alpha * np.tan(np.radians(theta_o_deg)) ** 2
    return 1.0 / (1.0 + u / (2.0 * (1.0 + np.sqrt(1.0 + u))))


def study(name, shadowing, grid_a, grid_b, keys, region):
    """Per parameter pair: max |G1 error| over theta_o <= 80 and at the grazing angles; the
    self-checks of the exact values; the stand-ins' errors (GTR)."""
    err = np.zeros((len(grid_a), len(grid_b)))
    err_graze = np.zeros((len(grid_a), len(grid_b), len(GRAZING)))
    naive = np.zeros_like(err)
    matched = np.zeros_like(err)
    where = {}
    refine = 0.0
    for i, pa in enumerate(grid_a):
        for j, pb in enumerate(grid_b):
            p = dict(zip(keys, (pa, pb)))
            lam = exact_lambda(name, p, THETA_O)
            refine = max(refine, float(np.max(np.abs(exact_lambda(name, p, THETA_O, 2 * N_THETA) - lam)
                                              / (1.0 + lam))))
            e = model_g1(shadowing, p, THETA_O) * (1.0 + lam) - 1.0
            k = int(np.argmax(np.abs(e)))
            err[i, j] = abs(e[k])
            where[i, j] = THETA_O[k]
            lg = exact_lambda(name, p, GRAZING)
            err_graze[i, j] = np.abs(model_g1(shadowing, p, GRAZING) * (1.0 + lg) - 1.0)
            if name == "gtr":
                alpha, gamma = pa, pb
                s = gamma - 1.0
                a_eff = np.sqrt(s * (1.0 - alpha ** 2) / np.expm1(-2.0 * s * np.log(alpha))) if alpha < 1 else 1.0
                naive[i, j] = np.max(np.abs(ggx_g1(alpha, THETA_O) * (1.0 + lam) - 1.0))
                matched[i, j] = np.max(np.abs(ggx_g1(a_eff, THETA_O) * (1.0 + lam) - 1.0))
    in_region = np.outer(region[0](grid_a), region[1](grid_b))
    return dict(err=err, where=where, graze=err_graze, naive=naive, matched=matched, refine=refine,
                region=in_region)


def cross_check(name, share, points):
    """Largest |difference| / (1 + Lambda) between the hemisphere integral and the share form."""
    worst = 0.0
    for p, th in points:
        lam = exact_lambda(name, p, [th])[0]
        alt = lambda_by_share(lambda t: share(t, *p.values()), np.tan(np.radians(th)))
        worst = max(worst, abs(lam - alt) / (1.0 + lam))
    return worst


def fmt(x):
    return f"{x:.1e}"


def table(res, grid_a, grid_b, la, lb, rows, cols):
    out = [f"| {la} \\ {lb} | " + " | ".join(f"{grid_b[j]:g}" for j in cols) + " |",
           "|---|" + "---|" * len(cols)]
    for i in rows:
        out.append(f"| {grid_a[i]:.3g} | " + " | ".join(fmt(res['err'][i, j]) for j in cols) + " |")
    return out


def summary(res, grid_a, grid_b, la, lb):
    e, reg = res["err"], res["region"]
    i, j = np.unravel_index(np.argmax(e), e.shape)
    ir, jr = np.unravel_index(np.argmax(np.where(reg, e, -1)), e.shape)
    lines = [f"- largest relative error of G1 over theta_o <= 80 deg, whole box: **{fmt(e[i, j])}** "
             f"({la} = {grid_a[i]:.3g}, {lb} = {grid_b[j]:g}, theta_o = {res['where'][i, j]:g} deg)",
             f"- in the region fits use: **{fmt(e[ir, jr])}** ({la} = {grid_a[ir]:.3g}, {lb} = {grid_b[jr]:g}, "
             f"theta_o = {res['where'][ir, jr]:g} deg)"]
    g = res["graze"]
    lines.append("- beyond the validated range (largest over the box): " + ", ".join(
        f"{GRAZING[k]:g} deg: {fmt(g[..., k].max())}" for k in range(len(GRAZING))))
    lines.append(f"- exact values: twice the theta nodes change 1 + Lambda by at most {fmt(res['refine'])}")
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(HERE / "results" / "lambda_gtr.md"))
    args = ap.parse_args()
    t0 = time.time()
    alphas = np.unique(np.concatenate([np.geomspace(1e-4, 1.0, 25), [0.005, 0.3]]))
    gammas = np.round(np.linspace(1.05, 4.0, 60), 4)
    gtr = study("gtr", "smith_gtr", alphas, gammas, ("alpha", "gamma"),
                (lambda a: (a >= 0.005 - 1e-12) & (a <= 0.3 + 1e-12), lambda g: (g >= 1.1 - 1e-9) & (g <= 3.0 + 1e-9)))
    Bs = np.geomspace(0.1, 1e8, 28)
    Cs = np.unique(np.round(np.concatenate([np.linspace(0.25, 8.0, 32), [1.0, 2.0]]), 4))
    abc = study("abc", "smith_abc", Bs, Cs, ("B", "C"),
                (lambda b: (b >= 10.0) & (b <= 1e5 + 1), lambda c: (c >= 0.5) & (c <= 6.0)))
    rng = np.random.default_rng(1)
    pts_gtr = [({"alpha": float(a), "gamma": float(g)}, float(t)) for a, g, t in
               zip(np.exp(rng.uniform(np.log(1e-3), 0, 12)), rng.uniform(1.05, 4, 12), rng.uniform(5, 80, 12))]
    pts_abc = [({"B": float(b), "C": float(c)}, float(t)) for b, c, t in
               zip(np.exp(rng.uniform(np.log(0.1), np.log(1e6), 8)), rng.uniform(0.25, 8, 8), rng.uniform(5, 80, 8))]
    chk_gtr, chk_abc = cross_check("gtr", share_gtr, pts_gtr), cross_check("abc", share_abc, pts_abc)
    elapsed = time.time() - t0

    ra = [int(np.argmin(np.abs(np.log(alphas / a)))) for a in (1e-4, 1e-3, 0.005, 0.01, 0.03, 0.1, 0.3, 0.6, 1.0)]
    cg = [int(np.argmin(np.abs(gammas - g))) for g in (1.05, 1.1, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0)]
    rb = list(range(0, len(Bs), 3))
    cc = [int(np.argmin(np.abs(Cs - c))) for c in (0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.5, 6.0, 8.0)]
    reg = gtr["region"]
    md = [f"# Smith Lambda of GTR and ABC against the exact Lambda ({datetime.date.today()})", "",
          "Made by `python bench/lambda_gtr.py` (its docstring says how the exact Lambda is computed). "
          "Error: |G1 / G1_exact - 1|, G1 = 1 / (1 + Lambda), the largest over theta_o = 1..80 deg "
          "(step 1 deg) for each parameter pair.", "",
          f"## GTR: `smith_gtr`, GGX's Lambda plus a {SERIES_TERMS}-term series in cos theta (from a "
          f"{HOST_NODES}-node rule on the host)", "",
          f"Grid: alpha {len(alphas)} values log-spaced over 1e-4..1, gamma {len(gammas)} values over "
          "1.05..4; region fits use: alpha 0.005..0.3, gamma 1.1..3.", "",
          *summary(gtr, alphas, gammas, "alpha", "gamma"),
          f"- exact values: hemisphere integral vs closed-form cumulative (share) form, 12 random points: "
          f"{fmt(chk_gtr)}",
          f"- gamma = 2 (GGX): {fmt(gtr['err'][:, int(np.argmin(np.abs(gammas - 2)))].max())}; "
          f"alpha = 1 (uniform D): {fmt(gtr['err'][-1].max())}", "",
          "For comparison, two cheaper stand-ins (largest error over theta_o <= 80 deg):", "",
          "| stand-in | whole box | region fits use |", "|---|---|---|",
          f"| GGX's Lambda, same alpha | {fmt(gtr['naive'].max())} | {fmt(np.where(reg, gtr['naive'], 0).max())} |",
          f"| GGX's Lambda, alpha matched at small theta_o | {fmt(gtr['matched'].max())} | "
          f"{fmt(np.where(reg, gtr['matched'], 0).max())} |",
          f"| the series (`smith_gtr`) | {fmt(gtr['err'].max())} | {fmt(np.where(reg, gtr['err'], 0).max())} |", "",
          "Largest error over theta_o <= 80 deg, by alpha (rows) and gamma (columns):", "",
          *table(gtr, alphas, gammas, "alpha", "gamma", ra, cg), "",
          f"## ABC: `smith_abc`, a {SERIES_TERMS}-term series in cos theta (from a {HOST_NODES}-node rule "
          "on the host)", "",
          f"Grid: B {len(Bs)} values log-spaced over 0.1..1e8, C {len(Cs)} values over 0.25..8 (1 and 2 "
          "included); region of the published fits: B 10..1e5, C 0.5..6.", "",
          *summary(abc, Bs, Cs, "B", "C"),
          f"- exact values: hemisphere integral vs share form (adaptive quadrature of the cumulative), "
          f"8 random points: {fmt(chk_abc)}", "",
          "Largest error over theta_o <= 80 deg, by B (rows) and C (columns):", "",
          *table(abc, Bs, Cs, "B", "C", rb, cc), "",
          f"Run time: {elapsed:.0f} s.", ""]
    text = "\n".join(md)
    print(text)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text)


if __name__ == "__main__":
    main()
