"""Which physical effect makes which part of each measured BRDF (docs/spec.md section 5).

For every material: the gradient test (brdfcl.analysis.gradient), the wavelength law
(brdfcl.analysis.law: the full model fitted with each channel's wavelength and with one), the
lobe comparison (brdfcl.optim.selection: fits with and without the diffraction and Cook-Torrance
lobes, sharing one load of the data), and the curve collapse (brdfcl.analysis.wavelength), which
pictures the law.  Each test is necessary, none sufficient (a broad Cook-Torrance lobe can tilt
the level lines like f does, a colour that changes with angle can favour the channels'
wavelengths, and a misfitting CT lobe can be patched by a diffraction lobe), so the verdict is
``diffraction`` only when the lobe comparison keeps the diffraction lobe, neither the gradient
test nor the law contradicts it, and at least one of them is evidence for it (``Rule``); ``none``
otherwise.  A material with verdict ``none`` gets its final fit without the diffraction lobe.

The thresholds (``RULE``) are chosen by the calibration (``brdfcl calibrate``,
brdfcl.analysis.calibration) on synthetic materials of known diffraction share, measured with
MERL-like noise and missing cells, on the tables themselves and after the NBRDF round trip of the
MERL-proxy, among them materials whose colour changes with angle by other means (thin films,
per-channel roughness, metals' dispersion): the rule of highest detection with at most 5% false
positives on each no-diffraction class of either kind of table (bench/results/calibration/
calibration.md has its rates).  The lobe comparison may fall short of keeping the lobe by 0.05
(the penalised errors nearly tie); where at least 100 gradient-test cells decide, a score below
0.3 contradicts; a law ratio of 1.25 or more contradicts; the evidence is a gradient score of at
least 0.5 or a law ratio below 0.99.  The rule is only as good as the no-diffraction classes it
was calibrated on (bench/results/calibration/NOTE.md).  Each verdict carries its margins
(``MaterialAnalysis.margins``).

The fits give the specular peak to Cook-Torrance (brdfcl.optim.peak_order, the talk's model);
the full model is also fitted without that constraint (``full_free``) so that the table
shows what the constraint costs and which lobe a free fit would put on the peak.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from brdfcl.analysis.gradient import GradientMap, gradient_test
from brdfcl.analysis.law import GREY, NO_TEST, LawTest, table_law
from brdfcl.analysis.wavelength import WavelengthCheck, wavelength_check
from brdfcl.data.geometry import bin_centres, directions
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.optim.peak_order import peak_cell
from brdfcl.optim.selection import select

# The verdict's thresholds, calibrated (bench/results/calibration/calibration.md)
MIN_DECIDABLE = 100           # gradient test cells below which it is inconclusive
GRADIENT_SCORE = 0.3          # gradient score below which the gradient test contradicts
GRADIENT_DECISIVE = 0.5       # gradient score from which the gradient test is evidence
GRADIENT_REQUIRED = False     # an inconclusive gradient test gives none
LOBE_GAIN = -0.05             # lobe comparison: ln(penalised error without / with diffraction)
WAVELENGTH_DECISIVE = 0.99    # law ratio below which the wavelength law is evidence
WAVELENGTH_VETO = 1.25        # law ratio at or above which the wavelength law contradicts
WAVELENGTH_TEST = "law"       # the ratio the rule reads (Rule.wavelength_test)
COMPARED = ("full", "no_diffraction", "no_ct")
TESTS = ("gradient", "wavelength", "lobe", "evidence")


def _scalar(x):
    x = np.asarray(x, dtype=float)
    return float(x) if x.ndim == 0 else x


@dataclass(frozen=True)
class Rule:
    """The verdict rule and its thresholds.  ``diffraction`` when the lobe comparison keeps the
    diffraction lobe by more than ``lobe_gain`` (ln of the penalised error without diffraction over
    the best with it; 0: brdfcl.optim.selection's choice), neither test of the physics contradicts
    it where it decides (the gradient test where at least ``min_cells`` cells decide: score below
    ``gradient_score``; the wavelength law: ratio at or above ``wavelength_veto``), and at least one
    of them is evidence for it (gradient score at least ``gradient_decisive``, or a ratio below
    ``wavelength_decisive``).  The ratio is the wavelength law's, its colour ratio's, the larger of
    the two, or the curve collapse's for the rules before the law test, as ``wavelength_test``
    says; with ``gradient_required`` the gradient test must decide.  The defaults are the
    calibrated rule (the calibration compares it with the rule before it,
    brdfcl.analysis.calibration_summary.LEGACY); scattered samples, which have no gradient test,
    are judged by the same rule without that requirement (brdfcl.analysis.samples.SAMPLE_RULE).

    ``margins`` gives each condition's signed distance to its threshold, positive on the side of
    diffraction: gradient ``score - gradient_score`` (NaN where too few cells decide), wavelength
    ``ln(wavelength_veto / ratio)`` (NaN where the ratio cannot be computed), lobe
    ``gain - lobe_gain``, evidence the larger of ``score - gradient_decisive`` and
    ``ln(wavelength_decisive / ratio)`` (of those that decide; units differ, only the sign and the
    size within one test mean something).  Margins and verdicts take numbers or arrays."""

    gradient_score: float = GRADIENT_SCORE
    gradient_decisive: float = GRADIENT_DECISIVE
    min_cells: int = MIN_DECIDABLE
    wavelength_decisive: float = WAVELENGTH_DECISIVE
    wavelength_veto: float = WAVELENGTH_VETO
    lobe_gain: float = LOBE_GAIN
    gradient_required: bool = GRADIENT_REQUIRED   # an undecided gradient test (too few cells) says none
    wavelength_test: str = WAVELENGTH_TEST        # whose ratio: "law", "colour", "both", "collapse"

    def wavelength_ratio(self, law_ratio, collapse_ratio, colour_ratio=float("nan")):
        """The ratio this rule's wavelength thresholds read: the law's, its colour ratio's
        (brdfcl.analysis.law), ``both``: the larger of the two (evidence only where the law holds
        on the whole table and on the colour alone; either contradicts; the law's alone where the
        colour ratio is unknown), or (the rule before the law test, kept to compare) the curve
        collapse's."""
        if self.wavelength_test == "both":
            return np.fmax(law_ratio, colour_ratio)
        return {"collapse": collapse_ratio, "colour": colour_ratio}.get(self.wavelength_test, law_ratio)

    def margins(self, grad_score, grad_cells, wl_ratio, lobe_gain) -> dict:
        s, n, r, g = (np.asarray(x, dtype=float) for x in (grad_score, grad_cells, wl_ratio, lobe_gain))
        with np.errstate(invalid="ignore", divide="ignore"):
            decided, valid = n >= self.min_cells, r >= 0
            evidence = np.fmax(np.where(decided, s - self.gradient_decisive, np.nan),
                               np.where(valid, np.log(self.wavelength_decisive / r), np.nan))
            return {"gradient": _scalar(np.where(decided, s - self.gradient_score, np.nan)),
                    "wavelength": _scalar(np.where(valid, np.log(self.wavelength_veto / r), np.nan)),
                    "lobe": _scalar(g - self.lobe_gain), "evidence": _scalar(evidence)}

    def against(self, margins: dict) -> dict:
        """{condition: whether it speaks against diffraction} (numbers or arrays): the lobe margin
        not positive, a test that decides and contradicts, no evidence (or, with
        ``gradient_required``, an undecided gradient test: counted against the gradient)."""
        m = {k: np.asarray(v, dtype=float) for k, v in margins.items()}
        grad = m["gradient"] < 0
        if self.gradient_required:
            grad = grad | ~np.isfinite(m["gradient"])
        return {"gradient": grad, "wavelength": m["wavelength"] <= 0, "lobe": ~(m["lobe"] > 0),
                "evidence": ~(m["evidence"] >= 0)}

    def diffraction(self, margins: dict):
        """Whether the verdict is ``diffraction`` (a bool, or a bool array for array margins)."""
        a = self.against(margins)
        out = ~(a["gradient"] | a["wavelength"] | a["lobe"] | a["evidence"])
        return bool(out) if out.ndim == 0 else out

    def verdict(self, margins: dict) -> str:
        """``diffraction`` when no condition speaks against it (``against``), else ``none``."""
        return "diffraction" if self.diffraction(margins) else "none"

    def binding(self, margins: dict) -> str:
        """The conditions the verdict hangs on: for ``diffraction`` the one nearest its threshold
        (least margin; units differ, so this names it rather than ranks it), for ``none`` every
        condition against it."""
        if self.verdict(margins) == "diffraction":
            decided = {k: v for k, v in margins.items() if np.isfinite(v)}
            return min(decided, key=lambda k: decided[k])
        against = self.against(margins)
        return "+".join(k for k in TESTS if bool(against[k]))


RULE = Rule()


@dataclass
class Analysis:
    """What every analysed material has, a table or scattered samples: the lobe comparison's fits
    and choice, the verdict and the peak shares; the evidence of each kind of data is a subclass's."""

    name: str
    verdict: str                          # "diffraction" or "none"
    selected: str                         # variant key chosen by the lobe comparison
    final_model: str
    fits: dict                            # variant key -> FitResult
    specs: dict                           # variant key -> model spec
    penalised: dict
    peak_share_diffraction: float         # share of the fitted peak value from the diffraction lobe
    peak_share_free: float                # the same for the fit without the peak constraint

    rule: Rule = RULE
    law: LawTest = NO_TEST                # the wavelength law's two fits compared (brdfcl.analysis.law)

    @property
    def law_ratio(self) -> float:
        """The law's statistic (LawTest.ratio): below 1, the wavelength enters as diffraction predicts."""
        return self.law.ratio

    def margins_raw(self) -> dict:
        """{test: margin} under the rule it was judged by (Rule.margins)."""
        raise NotImplementedError

    def margins(self) -> dict:
        """Each test's margin to its threshold (Rule.margins), the tests the verdict hangs on, and
        the lobe gain itself: the columns analysis.csv carries beside the verdict."""
        m = self.margins_raw()
        return {"margin_gradient": _fmt(m["gradient"]), "margin_wavelength": _fmt(m["wavelength"]),
                "margin_lobe": _fmt(m["lobe"]), "margin_evidence": _fmt(m["evidence"]),
                "lobe_gain": _fmt(m["lobe"] + self.rule.lobe_gain),
                "verdict_by": self.rule.binding(m)}

    @property
    def final(self):
        return final_fit(self.fits, self.specs, self.final_model)

    def head(self) -> dict:
        """The first columns of its analysis.csv row."""
        return {"material": self.name, "verdict": self.verdict, **self.margins(),
                "selected_lobes": self.specs[self.selected], "final_model": self.final_model}


@dataclass
class MaterialAnalysis(Analysis):
    """A table analysed: the gradient test and the wavelength check on its grid."""

    gradient: GradientMap = None          # type: ignore[assignment]
    wavelength: WavelengthCheck = None    # type: ignore[assignment]
    slices: dict = field(default_factory=dict)   # name -> (3, 90, 90) phi_d ~ 90 deg images

    def margins_raw(self) -> dict:
        return margins_of(self)

    def row(self):
        g, w = self.gradient, self.wavelength
        band = g.th_range_deg[1]
        out = self.head()
        for c, ch in enumerate("rgb"):
            out[f"grad_score_{ch}"] = _fmt(g.score[c])
        out["grad_cells"] = int(g.n_cells.sum())
        out["grad_band_deg_g"] = f"{band[0]:.1f}-{band[1]:.1f}" if band else ""
        out.update(law_columns(self))
        out["wavelength_spread"] = _fmt(w.spread)
        out["wavelength_spread_f0"] = _fmt(w.spread_f0)
        out["collapse_ratio"] = _fmt(w.ratio)
        return {**out, **fit_columns(self)}


def final_fit(fits: dict, specs: dict, final_model: str):
    """The compared fit of the final model."""
    return next(r for k, r in fits.items() if specs[k] == final_model and k in COMPARED)


def final_key(verdict: str, selected: str, fits: dict, specs: dict) -> str:
    """The variant a material's final fit is: the lobe comparison's choice, but without the
    diffraction lobe where the verdict is ``none``, and the full model where the verdict is
    ``diffraction`` although the choice (within the rule's lobe tolerance) dropped the lobe."""
    has = Model(specs[selected]).has_role("diffraction")
    if verdict == "none" and has:
        return "no_diffraction" if "no_diffraction" in fits else selected
    if verdict == "diffraction" and not has and "full" in fits:
        return "full"
    return selected


def fit_columns(a, extra: dict | None = None) -> dict:
    """The analysis.csv columns of an analysis's fits (a MaterialAnalysis or a SampleAnalysis):
    rmse_log and penalised error of each compared variant, ``extra``, then the free-peak fit and
    the peak shares."""
    out = {}
    for k in COMPARED:
        r = a.fits.get(k)
        out[f"rmse_log_{k}"] = _fmt(r.errors["rmse_log"]) if r else ""
        out[f"penalised_{k}"] = _fmt(a.penalised.get(k, np.nan)) if r else ""
    out.update(extra or {})
    free = a.fits.get("full_free")
    out["rmse_log_full_free"] = _fmt(free.errors["rmse_log"]) if free else ""
    out["peak_share_diffraction"] = _fmt(a.peak_share_diffraction)
    out["peak_share_free"] = _fmt(a.peak_share_free)
    return out


def law_columns(a) -> dict:
    """The analysis.csv columns of the wavelength law (brdfcl.analysis.law), the same for tables
    and samples: its ratio, the two wide-angle errors, the cells they cover, the grey fit's rmse_log."""
    grey = a.fits.get(GREY)
    return {"law_ratio": _fmt(a.law.ratio), "law_error": _fmt(a.law.error), "law_error_grey": _fmt(a.law.error_grey),
            "law_colour_ratio": _fmt(a.law.colour_ratio),
            "law_cells": a.law.n_cells, "rmse_log_full_grey": _fmt(grey.errors["rmse_log"]) if grey else ""}


def _fmt(x):
    return "" if x is None or not np.isfinite(x) else f"{x:.5g}"


def slice_cells(phi_bins=slice(80, 100)):
    """Cells of the phi_d ~ 90 deg slice (90 * 90 * 20), for model images matching the data slice."""
    th, td, pd = bin_centres()
    TH, TD, PD = np.meshgrid(th, td, pd[phi_bins], indexing="ij")
    wi, wo = directions(TH.ravel(), TD.ravel(), PD.ravel())
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    return Cells.from_directions(wi[ok], wo[ok]), ok, TH.shape


def lobe_images(spec, params):
    """(3, 90, 90) images of each lobe group at phi_d ~ 90: diffuse+diffraction, CT, full."""
    cells, ok, shape = slice_cells()
    out = {}
    model = Model(spec)
    groups = {"diffuse_diffraction": model.prefixes_with_role("diffuse", "diffraction"),
              "ct": model.prefixes_with_role("reflection"), "full": None}
    for key, keep in groups.items():
        p = np.full((3, ok.size), np.nan)
        p[:, ok] = model.reference(cells, model.only_lobes(params, keep), jacobian=False)
        with np.errstate(invalid="ignore", divide="ignore"):
            n = np.isfinite(p.reshape(3, *shape)).sum(-1)
            img = np.nansum(p.reshape(3, *shape), axis=-1) / np.maximum(n, 1)
        out[key] = np.where(n > 0, img, np.nan)
    return out


def peak_share(spec, params, lambdas=None):
    """Share of the fitted value at the specular peak (brdfcl.optim.peak_order.peak_cell) due to
    diffraction, for a model of the given channel wavelengths (default R, G, B)."""
    model = Model(spec) if lambdas is None else Model(spec, lambdas=tuple(lambdas))
    if not model.has_role("diffraction"):
        return 0.0
    cells = peak_cell()
    total = model.reference(cells, model.only_lobes(params, None), jacobian=False).sum()
    part = model.reference(cells, model.only_lobes(params, model.prefixes_with_role("diffraction")),
                           jacobian=False).sum()
    return float(part / max(total, 1e-300))


def lobe_gain(penalised: dict, specs: dict) -> float:
    """ln(best penalised error without a diffraction lobe / best with one): > 0 where the lobe
    comparison keeps the diffraction lobe (brdfcl.optim.selection)."""
    with_d = [v for k, v in penalised.items() if Model(specs[k]).has_role("diffraction")]
    without = [v for k, v in penalised.items() if not Model(specs[k]).has_role("diffraction")]
    if not with_d or not without:
        return float("inf") if with_d else float("-inf")
    return float(np.log(min(without) / min(with_d)))


def margins_of(a: MaterialAnalysis, rule: Rule | None = None) -> dict:
    """{test: margin} of a MaterialAnalysis under a rule (default: the one it was judged by)."""
    rule = rule or a.rule
    return rule.margins(a.gradient.mean_score, int(a.gradient.n_cells.sum()),
                        rule.wavelength_ratio(a.law_ratio, a.wavelength.ratio, a.law.colour_ratio),
                        lobe_gain(a.penalised, a.specs))


def analyze_material(name, brdf, fits, specs, rule: Rule | None = None) -> MaterialAnalysis:
    """Analyse one material from its fits (variant key -> FitResult; brdfcl.analysis.law.GREY:
    the full model at one wavelength, without which the law does not decide) under ``rule``
    (default RULE)."""
    rule = rule or RULE
    errors = {k: r.errors["rmse_log"] for k, r in fits.items() if r.success and k in COMPARED}
    sel, pen = select(errors, {k: specs[k] for k in errors})
    gm = gradient_test(brdf)
    full = fits["full"]
    full_model = Model(specs["full"])
    diffuse = [sum(full.params.get(lb.slot_name("rho", ch), 0.0) for lb in full_model.lobes_with_role("diffuse"))
               / np.pi for ch in range(3)]
    wl = wavelength_check(brdf, diffuse, full_model.lambdas)
    law = table_law(fits, specs["full"], full_model.lambdas, brdf)
    m = rule.margins(gm.mean_score, int(gm.n_cells.sum()), rule.wavelength_ratio(law.ratio, wl.ratio, law.colour_ratio),
                     lobe_gain(pen, specs))
    verdict = rule.verdict(m)
    free = fits.get("full_free")
    return MaterialAnalysis(name, verdict, sel, specs[final_key(verdict, sel, fits, specs)], fits, specs, pen,
                            peak_share(specs["full"], full.params),
                            peak_share(specs["full"], free.params) if free else float("nan"), rule=rule,
                            law=law, gradient=gm, wavelength=wl)


