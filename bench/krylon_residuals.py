"""Where a fit of scattered spectral samples misses: the shares of its rel_rmse by geometry and
band, its worst samples, and whether a diffuse that falls at grazing would fit better.

rel_rmse = sqrt(sum w ((p - m) cos ti)^2 / sum w (m cos ti)^2) over the fitted samples (within the
fit's cutoff) is a relative L2 error: it is decided by the largest values, the specular peak.
The diffuse study holds the fit's other lobes and refits each band's diffuse albedo (weighted
least squares in the same L2) under each shape: Lambert; Ashikhmin-Shirley's
(1 - (1 - cos/2)^5) at both directions; dielectric Fresnel transmission T(ti) T(to) / T(0)^2 with
eta searched; (cos ti cos to)^p with p searched.  A shape that cannot lower the error with the
rest held cannot be what the rest of the fit lacks.

    brdfcl fit-all FOLDER_WITH_krylon_blue.brdf --out OUT
    python bench/krylon_residuals.py ../shared/data/cornell/krylon_blue.brdf OUT/krylon_blue.json
"""
from __future__ import annotations

import argparse
import json

import numpy as np

from brdfcl.data.readers import read_samples
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.terms import REGISTRY


def _fresnel(c, eta):
    """brdfcl's dielectric Fresnel term (float64 reference) at cos theta_d = ``c``: evaluated on
    mirror cells (theta_h = 0), where theta_d is the angle of incidence."""
    s = np.sqrt(1 - c**2)
    cells = Cells.from_directions(np.stack([s, 0 * c, c], -1), np.stack([-s, 0 * c, c], -1))
    return REGISTRY["fresnel"]["dielectric"].reference(cells, eta=eta)[0]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("samples")
    ap.add_argument("fit", help="the material's NAME.json from brdfcl fit-all")
    ap.add_argument("--cutoff", type=float, default=80.0, help="theta cutoff of the fit (deg)")
    a = ap.parse_args(argv)
    s = read_samples(a.samples)
    doc = json.loads(open(a.fit).read())
    model = Model(doc["model"], lambdas=tuple(s.wavelengths))
    vals = {n: d["value"] for n, d in doc["params"].items()}
    ok = s.mask(a.cutoff)
    cells = Cells.from_directions(s.wi[ok], s.wo[ok])
    w = s.weights_within(a.cutoff)[ok][:, None]
    m = s.values[ok]
    cw = cells.ci[:, None]
    full = model.reference(cells, model.only_lobes(vals, None), jacobian=False).T
    diffuse = [lb.prefix for lb in model.lobes if lb.role == "diffuse"]
    rest = model.reference(cells, model.only_lobes(vals, [lb.prefix for lb in model.lobes
                                                         if lb.prefix not in diffuse]), jacobian=False).T
    den = np.sum(w * (m * cw) ** 2)

    def rel(p):
        return float(np.sqrt(np.sum(w * ((p - m) * cw) ** 2) / den))

    num = (w * ((full - m) * cw) ** 2).sum(1)
    ti, to = np.degrees(np.arccos(cells.ci)), np.degrees(np.arccos(cells.co))
    th = np.degrees(np.arccos(np.clip(cells.ch, -1, 1)))
    print(f"# {s.name}: {doc['model']} ({doc.get('form', '')}), {ok.sum()} samples, {len(s.wavelengths)} bands")
    print(f"rel_rmse {rel(full):.4f} (NAME.json: {doc['errors']['rel_rmse']:.4f})\n")
    print("| theta_h (deg) | samples | share of the error |\n|---|---|---|")
    for lo, hi in [(0, 5), (5, 10), (10, 20), (20, 40), (40, 90)]:
        sel = (th >= lo) & (th < hi)
        print(f"| {lo}-{hi} | {sel.sum()} | {num[sel].sum() / num.sum():.3f} |")
    print("\n| theta_i (deg) | samples | share of the error |\n|---|---|---|")
    for lo in range(0, 90, 15):
        sel = (ti >= lo) & (ti < lo + 15)
        if sel.any():
            print(f"| {lo}-{lo + 15} | {sel.sum()} | {num[sel].sum() / num.sum():.3f} |")
    mid = len(s.wavelengths) // 2
    print(f"\nworst samples (values of band {s.wavelengths[mid] * 1000:g} nm, sr^-1):\n")
    print("| theta_i | theta_o | theta_h | measured | fitted | share |\n|---|---|---|---|---|---|")
    for j in np.argsort(-num)[:5]:
        print(f"| {ti[j]:.0f} | {to[j]:.0f} | {th[j]:.1f} | {m[j, mid]:.3g} | {full[j, mid]:.3g} | "
              f"{num[j] / num.sum():.3f} |")

    def refit(shape):
        b = shape[:, None] / np.pi * cw
        r = (m - rest) * cw
        rho = np.clip(np.sum(w * b * r, 0) / np.sum(w * b * b, 0), 0, None)
        return rel(rest + b / cw * rho)

    ci, co = cells.ci, cells.co
    print("\ndiffuse shapes, the other lobes held:\n\n| shape | rel_rmse |\n|---|---|")
    print(f"| Lambert | {refit(np.ones_like(ci)):.4f} |")
    print(f"| Ashikhmin-Shirley | {refit((1 - (1 - ci / 2) ** 5) * (1 - (1 - co / 2) ** 5)):.4f} |")
    etas = np.linspace(1.01, 6.0, 200)
    e = [refit((1 - _fresnel(ci, x)) * (1 - _fresnel(co, x)) / (1 - _fresnel(np.ones(1), x)) ** 2) for x in etas]
    print(f"| Fresnel transmission, best eta {etas[int(np.argmin(e))]:.2f} | {min(e):.4f} |")
    ps = np.linspace(0.0, 2.0, 201)
    e = [refit((ci * co) ** p) for p in ps]
    print(f"| (cos ti cos to)^p, best p {ps[int(np.argmin(e))]:.2f} | {min(e):.4f} |")


if __name__ == "__main__":
    main()
