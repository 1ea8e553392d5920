"""How much diffraction can the tests see?  Synthetic materials with a known diffraction share,
measured as MERL would measure them, analysed as ``brdfcl analyze`` analyses a database.

A calibration case is a three-lobe material (brdfcl.model) of one class:

* diffraction classes (``halo-hp``, ``halo-abc``, ``halo-gauss``): a metal-like Cook-Torrance
  peak (GGX, Smith, Schlick) with a diffraction halo whose PSD is the fitted one (hp) or another
  (abc with its falloff exponent c, gauss), at a set diffraction *share*: the diffraction lobe's
  part of the wide-angle energy of the two non-diffuse lobes,
  ``E_diffraction / (E_diffraction + E_CT)``, ``E = sum over cells of p cos theta_i x cell measure``
  over the region where the gradient test looks (theta_h >= 5 deg, theta_d <= 75 deg,
  theta_i <= 80 deg, every phi_d), the same share in each channel;
* no-diffraction classes (share 0): a smooth metal with the fitted NDF (``metal-ggx``), a smooth
  metal whose NDF is not the fitted one (``metal-other``: Beckmann, or the exponential power
  distribution with heavier tails), a rough metal (``rough-metal``), a plastic (``plastic``:
  coloured diffuse base under a dielectric coat), a layered material (``layered``: a narrow
  dielectric coat lobe over a broad glossy base lobe, two Cook-Torrance lobes that the fitted
  model can only match with one, or with a diffraction lobe for the second) and a fabric-like
  faint broad sheen (``fabric``).

Parameters are drawn in the ranges the fits to the MERL-proxy give metals and plastics (alpha 0.006
to 0.06 for smooth metals, PSD corner a 0.15 to 2 1/um).  Measurement effects (``Effects``), all
drawn per material: multiplicative log-normal noise of 1 to 4% per cell and channel (MERL-like),
rising by 10 to 30% towards grazing (max(theta_i, theta_o) from 60 to 85 deg), 0.5 to 3% of cells
missing at random and every cell beyond 86 deg missing.

``fit_compared`` fits the compared variants as brdfcl.app.analyze does (the peak constraint with
both global searches, best kept; no ``full_free`` fit, which no verdict reads), and
``analyse_cases`` returns one row of raw statistics per case: what each test measured, not only
its verdict, so that brdfcl.analysis.power can evaluate any threshold without fitting again.

About 340 lines, one module: the cases, their measurement effects and their analysis are one
description of the study; split, each part would need the others' constants.
"""
from __future__ import annotations

import time
import zlib
from dataclasses import dataclass, field, replace

import numpy as np

from brdfcl.analysis.analyze import analyze_material, margins_of, peak_share
from brdfcl.analysis.gradient import PHI_BINS
from brdfcl.analysis.law import GREY, WIDE_STRIDE, grey_fitters, wide_cells
from brdfcl.data.geometry import table_geometry
from brdfcl.data.merl import N_PD, N_TD, N_TH, SCALE, MerlTable
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.synth import demo_values, tabulate
from brdfcl.optim.fit import FitOptions, Fitter
from brdfcl.optim.selection import variants

POWER_CLASSES = ("halo-hp", "halo-abc", "halo-gauss")
NULL_CLASSES = ("metal-ggx", "metal-other", "rough-metal", "plastic", "layered", "fabric")
COLOUR_CLASSES = ("thin-film", "channel-roughness", "metal-dispersion")
"""No-diffraction classes whose colour changes with angle for reasons other than diffraction."""
SHARES = (0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 0.9)


@dataclass
class Effects:
    """Measurement effects of one material (drawn per material by ``draw_effects``)."""

    noise: float = 0.02          # relative noise (log-normal sigma) per cell and channel
    grazing: float = 0.2         # extra sigma at and beyond GRAZING_DEG[1]
    missing: float = 0.01        # share of cells missing at random
    cutoff_deg: float = 86.0     # cells with theta_i or theta_o beyond this are missing


GRAZING_DEG = (60.0, 85.0)


@dataclass
class Case:
    name: str
    cls: str
    share: float                 # true diffraction share of the wide-angle energy (0: none)
    spec: str
    params: dict                 # {name: scalar or (r, g, b)} as brdfcl.model.synth.DEMO
    effects: Effects
    seed: int
    film: tuple | None = None    # (index, thickness um, substrate index) of a film on the facets

    @property
    def has_diffraction(self):
        return self.share > 0


@dataclass
class Plan:
    """How many cases of which class: ``reps`` per share for the diffraction classes, ``nulls``
    per no-diffraction class; every ``roundtrip_every``-th case also goes through NBRDF."""

    shares: tuple = SHARES
    reps: dict = field(default_factory=lambda: {"halo-hp": 6, "halo-abc": 3, "halo-gauss": 3})
    nulls: dict = field(default_factory=lambda: {"metal-ggx": 14, "metal-other": 12, "rough-metal": 16,
                                                 "plastic": 12, "layered": 16, "fabric": 8, "thin-film": 10,
                                                 "channel-roughness": 10, "metal-dispersion": 10})
    roundtrip_every: int = 2          # diffraction cases: every n-th of each class and share
    roundtrip_every_null: int = 1     # no-diffraction cases: the false positives on proxies hang on them
    seed: int = 0

    def cases(self):
        """The cases; each is drawn from its own seed (the plan's and its name), so that adding
        cases leaves the others as they were."""
        out = []
        for cls, n in self.reps.items():
            for s in self.shares:
                out += [draw_case(cls, s, f"{cls}-s{s:g}-{r}", self.seed) for r in range(n)]
        for cls, n in self.nulls.items():
            out += [draw_case(cls, 0.0, f"{cls}-{r}", self.seed) for r in range(n)]
        return out

    def roundtrip(self, cases):
        """The cases that also go through the NBRDF round trip."""
        seen, out = {}, []
        for c in cases:
            k = (c.cls, c.share)
            every = self.roundtrip_every if c.has_diffraction else self.roundtrip_every_null
            if seen.get(k, 0) % every == 0:
                out.append(c)
            seen[k] = seen.get(k, 0) + 1
        return out


QUICK = Plan(shares=(0.1, 0.7), reps={"halo-hp": 1}, nulls={"metal-ggx": 1, "plastic": 1}, roundtrip_every=1)


def _loguniform(rng, lo, hi):
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _tint(rng, value, spread):
    return tuple(float(value * rng.uniform(1 - spread, 1 + spread)) for _ in range(3))


def draw_effects(rng) -> Effects:
    return Effects(noise=rng.uniform(0.01, 0.04), grazing=rng.uniform(0.1, 0.3), missing=rng.uniform(0.005, 0.03))


MAX_PEAK_SHARE = 0.5
"""A diffraction case's lobe gives at most this share of the value at the specular peak (the talk's
model: the peak is Cook-Torrance's; brdfcl.optim.peak_order asks the same of the fits)."""


def draw_case(cls, share, name, seed=0, tries=50) -> Case:
    """One material of a class, its diffraction amplitudes set from the share (``case_values``);
    a diffraction case is drawn again while its lobe would carry the specular peak."""
    rng = np.random.default_rng([seed, zlib.crc32(name.encode())])
    for _ in range(tries):
        case = _draw(cls, share, rng, name)
        if not case.has_diffraction:
            return case
        model, v = case_values(case)
        if peak_share(case.spec, model.as_dict(v)) <= MAX_PEAK_SHARE:
            return case
    raise RuntimeError(f"{name}: no draw with the peak left to Cook-Torrance in {tries} tries")


def _draw(cls, share, rng, name) -> Case:
    seed = int(rng.integers(2 ** 31))
    diffuse = {"diffuse.rho": _tint(rng, _loguniform(rng, 1e-3, 3e-2), 0.3)}
    metal = {"ct.rho": _tint(rng, _loguniform(rng, 0.15, 0.8), 0.2),
             "ct.F0": tuple(float(min(x, 0.98)) for x in _tint(rng, rng.uniform(0.3, 0.9), 0.15))}
    if cls in POWER_CLASSES:
        psd = cls.split("-")[1]
        p = {**diffuse, **metal, "ct.alpha": _loguniform(rng, 0.006, 0.06),
             "diffraction.a": _loguniform(rng, 0.15, 2.0), "diffraction.rho": (1.0, 1.0, 1.0)}
        if psd == "abc":
            p["diffraction.c"] = rng.uniform(1.5, 6.0)
        spec = f"diffuse+diffraction:{psd}:none+ggx:smith:schlick"
    elif cls == "metal-ggx":
        spec, p = "diffuse+ggx:smith:schlick", {**diffuse, **metal, "ct.alpha": _loguniform(rng, 0.006, 0.06)}
    elif cls == "metal-other":
        if rng.random() < 0.5:
            spec, p = "diffuse+beckmann:smith:schlick", {**diffuse, **metal, "ct.alpha": _loguniform(rng, 0.008, 0.08)}
        else:
            spec = "diffuse+epd:vcavity:schlick"
            p = {**diffuse, **metal, "ct.beta": _loguniform(rng, 0.008, 0.08), "ct.p": rng.uniform(0.4, 0.9)}
    elif cls == "rough-metal":
        ndf = "ggx" if rng.random() < 0.5 else "beckmann"
        spec, p = f"diffuse+{ndf}:smith:schlick", {**diffuse, **metal, "ct.alpha": _loguniform(rng, 0.1, 0.5)}
    elif cls == "layered":         # a clear coat over a glossy base: two specular lobes, no diffraction
        base = "ggx" if rng.random() < 0.5 else "beckmann"
        spec = f"diffuse+ggx:smith:dielectric+{base}:smith:schlick"
        p = {"diffuse.rho": _tint(rng, _loguniform(rng, 0.005, 0.2), 0.5),
             "ct.rho": _tint(rng, rng.uniform(0.6, 1.0), 0.02), "ct.alpha": _loguniform(rng, 0.005, 0.04),
             "ct.eta": rng.uniform(1.4, 1.7), "ct2.rho": _tint(rng, _loguniform(rng, 0.03, 0.5), 0.3),
             "ct2.alpha": _loguniform(rng, 0.08, 0.4), "ct2.F0": _tint(rng, rng.uniform(0.2, 0.9), 0.2)}
    elif cls == "fabric":          # a faint, very broad sheen over a coloured diffuse base
        spec = "diffuse+beckmann:vcavity:none"
        p = {"diffuse.rho": _tint(rng, _loguniform(rng, 0.05, 0.5), 0.5),
             "ct.rho": _tint(rng, _loguniform(rng, 0.02, 0.15), 0.2), "ct.alpha": rng.uniform(0.35, 0.8)}
    elif cls == "plastic":
        ndf = "ggx" if rng.random() < 0.5 else "beckmann"
        spec = f"diffuse+{ndf}:smith:dielectric"
        p = {"diffuse.rho": _tint(rng, _loguniform(rng, 0.02, 0.5), 0.6),
             "ct.rho": _tint(rng, rng.uniform(0.6, 1.0), 0.02), "ct.alpha": _loguniform(rng, 0.01, 0.3),
             "ct.eta": rng.uniform(1.4, 1.7)}
    elif cls in COLOUR_CLASSES:
        return _draw_colour(cls, rng, name, diffuse, metal, seed)
    else:
        raise ValueError(f"unknown calibration class '{cls}'; valid: "
                         f"{', '.join(POWER_CLASSES + NULL_CLASSES + COLOUR_CLASSES)}")
    return Case(name, cls, float(share), spec, p, draw_effects(rng), seed)


METALS = {"gold": ((0.17, 0.45, 1.40), (3.15, 2.40, 1.85)), "copper": ((0.21, 1.00, 1.20), (3.67, 2.58, 2.40)),
          "brass": ((0.44, 0.53, 1.10), (3.70, 2.60, 1.90)), "aluminium": ((1.50, 0.96, 0.62), (7.70, 6.40, 5.40)),
          "iron": ((2.90, 2.90, 2.50), (3.00, 2.90, 2.80))}
"""Complex indices (eta, k) at the R, G, B wavelengths of metals whose reflectance changes colour
with angle (gold, copper, brass most; PBRT's and refractiveindex.info's tables, rounded)."""


def _draw_colour(cls, rng, name, diffuse, metal, seed) -> Case:
    """A no-diffraction material whose colour changes with angle by other means: a thin dielectric
    film on the facets of a Cook-Torrance lobe (interference: the phase follows the angle inside
    the film, not 2 sin th cos td), a roughness per channel (three lobes, one per channel, as SGD
    fits it), or a metal's own Fresnel dispersion (the exact conductor term, per-channel eta, k)."""
    ndf = "ggx" if rng.random() < 0.5 else "beckmann"
    if cls == "thin-film":
        spec = f"diffuse+{ndf}:smith:none"
        p = {**diffuse, "ct.rho": _tint(rng, rng.uniform(0.6, 1.0), 0.02), "ct.alpha": _loguniform(rng, 0.01, 0.2)}
        film = (rng.uniform(1.8, 2.5), rng.uniform(0.15, 0.6), rng.uniform(1.45, 1.6))
        return Case(name, cls, 0.0, spec, p, draw_effects(rng), seed, film=film)
    if cls == "channel-roughness":
        spec = f"diffuse+{ndf}:smith:schlick+{ndf}:smith:schlick+{ndf}:smith:schlick"
        alpha = _loguniform(rng, 0.01, 0.2)
        p = dict(diffuse)
        for c, pre in enumerate(("ct", "ct2", "ct3")):
            rho = [0.0, 0.0, 0.0]
            rho[c] = metal["ct.rho"][c]
            p.update({f"{pre}.rho": tuple(rho), f"{pre}.F0": metal["ct.F0"],
                      f"{pre}.alpha": alpha * (1.0 if c == 1 else _loguniform(rng, 0.6, 1.6))})
        return Case(name, cls, 0.0, spec, p, draw_effects(rng), seed)
    eta, k = METALS[list(METALS)[int(rng.integers(len(METALS)))]]
    p = {**diffuse, "ct.rho": _tint(rng, rng.uniform(0.6, 1.0), 0.05),
         "ct.alpha": _loguniform(rng, 0.006, 0.1),
         "ct.eta": tuple(float(x * rng.uniform(0.9, 1.1)) for x in eta),
         "ct.k": tuple(float(x * rng.uniform(0.9, 1.1)) for x in k)}
    return Case(name, cls, 0.0, f"diffuse+{ndf}:smith:conductor", p, draw_effects(rng), seed)


def film_reflectance(theta, lambdas, film) -> np.ndarray:
    """(C, n) unpolarised reflectance of a thin dielectric film (index, thickness in um) on a
    dielectric substrate (index), in air, at incidence angles ``theta`` (n,) and wavelengths
    ``lambdas`` (C,) in um: the Airy sum of the two interfaces' Fresnel amplitudes."""
    n1, d, n2 = film
    s0 = np.sin(theta)
    c0 = np.cos(theta)
    c1 = np.sqrt(1.0 - (s0 / n1) ** 2)
    c2 = np.sqrt(1.0 - (s0 / n2) ** 2)
    phase = np.exp(4j * np.pi * n1 * d * c1[None, :] / np.asarray(lambdas, dtype=float)[:, None])
    out = 0.0
    for r01, r12 in (((c0 - n1 * c1) / (c0 + n1 * c1), (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)),
                     ((n1 * c0 - c1) / (n1 * c0 + c1), (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2))):
        r = (r01 + r12 * phase) / (1.0 + r01 * r12 * phase)
        out = out + 0.5 * np.abs(r) ** 2
    return np.asarray(out)


# --- synthesis ----------------------------------------------------------------------------------
def lobe_energies(model: Model, values, stride=WIDE_STRIDE):
    """{role: (C,) wide-angle energy} of a model's lobes grouped by role."""
    cells, _, w = wide_cells(stride)
    params = model.as_dict(values)
    out = {}
    for role in ("diffuse", "diffraction", "reflection"):
        keep = model.prefixes_with_role(role)
        if keep:
            out[role] = model.reference(cells, model.only_lobes(params, keep), jacobian=False) @ w
    return out


def case_values(case: Case):
    """(Model, value vector) with the diffraction amplitudes set to the case's share."""
    model = Model(case.spec)
    v = demo_values(model, case.params)
    if model.has_role("diffraction"):
        e = lobe_energies(model, v)
        k = case.share / (1.0 - case.share) * e["reflection"] / e["diffraction"]   # diffraction.rho was 1
        for ch, name in enumerate(model.channels):
            v[model.names.index(f"diffraction.rho_{name}")] = k[ch]
    return model, v


def measured_share(model: Model, values):
    e = lobe_energies(model, values)
    d = e.get("diffraction", np.zeros(3))
    return float(np.mean(d / (d + e["reflection"])))


def measure(table, effects: Effects, seed):
    """The table as a MERL-like measurement: noise, grazing noise, missing cells (NaN)."""
    g = table_geometry()
    rng = np.random.default_rng(seed)
    t_max = np.degrees(np.arccos(np.clip(np.minimum(g.cos_i, g.cos_o), -1, 1)))
    ramp = np.clip((t_max - GRAZING_DEG[0]) / (GRAZING_DEG[1] - GRAZING_DEG[0]), 0, 1) ** 2
    sigma = effects.noise + effects.grazing * ramp
    out = table * np.exp(sigma * rng.standard_normal(table.shape) - 0.5 * sigma ** 2)
    drop = (rng.random(t_max.size) < effects.missing) | (t_max > effects.cutoff_deg)
    out[:, drop] = np.nan
    return out


def synthesize(case: Case, index=None):
    """(clean table, measured table), each (3, N_CELLS) in 1/sr, NaN where missing; with ``index``
    (table indices) only those cells are tabulated, the rest NaN (e.g. ``SLICE``, all that the
    gradient test and the wavelength check read, for quick checks).  A case with a film has its
    reflection lobe's facets reflect as the film does (``film_reflectance`` at theta_d, the
    angle of incidence on a facet) instead of with F = 1."""
    model, v = case_values(case)
    clean = _table(model, v, index)
    if case.film is not None:
        facets = _table(model, model.only_lobes(model.as_dict(v), model.prefixes_with_role("reflection")), index)
        clean = clean + facets * (film_reflectance(table_geometry().theta_d, model.lambdas, case.film) - 1.0)
    return clean, measure(clean, case.effects, case.seed)


def _table(model: Model, values, index=None):
    if index is None:
        return tabulate(model, values)
    g = table_geometry()
    index = index[g.above_horizon[index]]
    out = np.full((model.n_channels, g.theta_h.size), np.nan)
    out[:, index] = model.reference(Cells.from_geometry(g, index), values, jacobian=False)
    return out


def slice_index():
    """Table indices of the phi_d ~ 90 deg slice that the gradient test and wavelength check read."""
    k = np.arange(N_TH * N_TD)[:, None] * N_PD + np.arange(N_PD)[PHI_BINS][None, :]
    return k.ravel()


def as_merl(name, brdf):
    valid = np.isfinite(brdf).all(axis=0)
    return MerlTable(name, None, brdf / SCALE[:, None], int((~valid).sum()))


# --- analysis -----------------------------------------------------------------------------------
class Compared:
    """The fitters of the compared variants, built once (as brdfcl.app.analyze.analyze builds them,
    less the ``full_free`` fit, which no verdict reads)."""

    def __init__(self, options: FitOptions | None = None):
        opts = options or FitOptions()
        self.specs = variants(Model(opts.model).spec)
        self.fitters = {k: Fitter(replace(opts, model=s, fixed={}, ct_peak=True)) for k, s in self.specs.items()}
        base = self.fitters["full"]
        self.fitters["full_local"] = Fitter(replace(base.opts, ct_peak_global=False), engine=base.engine)
        self.fitters.update(grey_fitters(base, base.model.lambdas, ct_peak=True))
        for f in self.fitters.values():
            f.assess_results = False            # standard errors and albedo: no verdict reads them

    def fit(self, tables, log=None):
        """{variant: {name: FitResult}} for MerlTables, the full fit the better of both searches."""
        fits = {}
        tables = list(tables)
        loaded = self.fitters["full"].load(tables)           # every variant fits the same cells
        for k, f in self.fitters.items():
            t = time.perf_counter()
            fits[k] = {r.name: r for r in f.fit_loaded(loaded)}
            if log:
                log(f"  fitted {len(loaded.names)} with {k} in {time.perf_counter() - t:.1f} s")
        for key in ("full", GREY):
            other = fits.pop(key + "_local")
            fits[key] = {n: (r if r.loss <= other[n].loss else other[n]) for n, r in fits[key].items()}
        return fits


def statistics(a) -> dict:
    """The raw statistics of one MaterialAnalysis that the verdict rule reads, and the verdict and
    margins under the rule it was analysed with (``verdict_rule``; brdfcl.analysis.power reads only
    the statistics, so any rule can be applied later)."""
    g, w = a.gradient, a.wavelength
    pen = a.penalised
    with_d = [pen[k] for k in pen if "diffraction" in a.specs[k]]
    without = [pen[k] for k in pen if "diffraction" not in a.specs[k]]
    return {"grad_score": g.mean_score, "grad_cells": int(g.n_cells.sum()), "wl_ratio": w.ratio,
            "law_ratio": a.law_ratio, "law_error": a.law.error, "law_error_grey": a.law.error_grey,
            "law_colour_ratio": a.law.colour_ratio,
            "rmse_grey": a.fits[GREY].errors["rmse_log"],
            "lobe_gain": float(np.log(min(without) / min(with_d))) if with_d and without else float("nan"),
            "rmse_full": a.fits["full"].errors["rmse_log"],
            "rmse_no_diffraction": a.fits["no_diffraction"].errors["rmse_log"],
            "verdict": a.verdict, "verdict_rule": str(a.rule), **{f"margin_{k}": v for k, v in margins_of(a).items()}}


def analyse_cases(cases, tables, compared: Compared, batch=8, log=None, tag=""):
    """One row per case: the case, its statistics and the verdict of the current rule.
    ``tables`` maps case name -> measured table (3, N_CELLS) or a callable returning one."""
    rows = []
    for s in range(0, len(cases), batch):
        part = cases[s:s + batch]
        t0 = time.perf_counter()
        brdfs = {c.name: (tables[c.name]() if callable(tables[c.name]) else tables[c.name]) for c in part}
        fits = compared.fit([as_merl(n, b) for n, b in brdfs.items()], log=log)
        specs = dict(compared.specs)
        for c in part:
            a = analyze_material(c.name, brdfs[c.name], {k: fits[k][c.name] for k in fits}, specs)
            rows.append({"case": c.name, "class": c.cls, "share": c.share, "table": tag, "spec": c.spec,
                         "noise": c.effects.noise, "missing": c.effects.missing, **statistics(a)})
        if log:
            log(f"{tag} {s + len(part)}/{len(cases)} analysed ({time.perf_counter() - t0:.1f} s for {len(part)})")
    return rows
