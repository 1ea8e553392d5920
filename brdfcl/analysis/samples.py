"""The analysis of scattered spectral samples (a gonioreflectometer's, a Cornell ``.brdf``): the
lobe comparison as for tables and the spectral wavelength check, without the gradient test.

The gradient test needs the data's gradient on a regular (theta_h, theta_d) grid; scattered
samples have none, and the test run on the model fitted to them would only test the model, so it
is not run and the report says so.  Its place in the verdict is taken by the wavelength law,
which with tens of bands is far sharper than on a table's three channels: the full model is
fitted with each band's wavelength in f_c = f0 / lambda_c (diffraction) and with every band at the
middle band's wavelength (the same parameters, scattering that ignores the wavelength;
``grey_lambdas``), each from the same two global searches (with and without the peak constraint
there; the better fit kept), so that neither side gets more tries.  ``law_ratio`` =
rmse_log(lambda_c) / rmse_log(grey) < 1 says the wavelength enters as diffraction predicts.  The
verdict (``SAMPLE_RULE``) is ``diffraction`` when the lobe comparison keeps the diffraction lobe
and law_ratio < 1; ``none`` otherwise.

The collapse of the residual band curves (brdfcl.analysis.spectral, drawn in the figure) is
reported beside it but does not decide: it subtracts a fit whose per-band diffuse level can
absorb the wavelength dependence.  On a synthetic halo made at one wavelength in every band it
gave a spread ratio of 0.34 (collapse against f_c) from the fit's residual, 29.6 with the true
diffuse level; the law ratio gave 5.2 (rmse_log 0.0067 against 0.0013 at 1% noise), and 0.23 on
the same halo made with each band's wavelength.  The fitted exponent of lambda is reported, not
used: it assumes a spectrally flat surface reflectance, which a coloured paint is not.

This rule was not calibrated as the table's was (brdfcl calibrate): its threshold is the comparison's
own (1: the wavelength law fits no better than none), and it was checked on synthetic spectral
materials with and without diffraction (tests/test_analyze_samples.py).  The lobe comparison
penalises a spectral lobe as its RGB counterpart (brdfcl.optim.selection counts parameters on
the RGB model), so that it keeps the meaning it has on tables.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdfcl._words import count
from brdfcl.analysis.analyze import COMPARED, Analysis, Rule, _fmt, final_key, fit_columns, lobe_gain, peak_share
from brdfcl.analysis.spectral import SpectralCheck, spectral_check
from brdfcl.data.samples import Samples
from brdfcl.model.compose import Model
from brdfcl.optim.selection import select

LAW_RATIO = 1.0               # rmse_log with lambda_c over rmse_log with one wavelength: below, diffraction
SAMPLE_RULE = Rule(wavelength_decisive=LAW_RATIO, gradient_required=False, wavelength_required=True)
GREY = "full_grey"            # the fit key of the full model with every band at one wavelength
GREY_STEP = 1e-5              # the grey bands' relative offsets, so that their channel names stay distinct


def grey_lambdas(lambdas) -> tuple:
    """Every band at the middle band's wavelength (band i offset by i x GREY_STEP relative, which
    moves f by at most 1e-3 for 100 bands, and keeps the channel names distinct at any wavelength):
    the wavelength law of scattering that ignores the wavelength."""
    mid = float(lambdas[len(lambdas) // 2])
    return tuple(mid * (1.0 + GREY_STEP * i) for i in range(len(lambdas)))


GRADIENT_NOT_RUN = "not run: scattered samples have no (theta_h, theta_d) grid"


@dataclass
class SampleAnalysis(Analysis):
    """One material's scattered samples analysed: the wavelength law by model comparison and the
    spectral collapse, no gradient test."""

    rule: Rule = SAMPLE_RULE
    spectral: SpectralCheck | None = None   # None: too few wide-angle samples or bands
    samples: Samples = None                 # type: ignore[assignment]  # the measurement (for the figures)
    gradient = None                         # the gradient test is not run (module docstring)

    @property
    def lambdas(self) -> tuple:
        return tuple(float(x) for x in self.samples.wavelengths)

    @property
    def law_ratio(self) -> float:
        """rmse_log of the full fit with each band's wavelength over that with one wavelength."""
        return law_ratio(self.fits)

    def margins_raw(self) -> dict:
        return self.rule.margins(float("nan"), 0, self.law_ratio, lobe_gain(self.penalised, self.specs))

    def row(self) -> dict:
        s = self.spectral
        out = {**self.head(),
               "data": f"{count(self.samples.n_samples, 'scattered sample')}, {count(len(self.lambdas), 'band')}",
               "gradient_test": GRADIENT_NOT_RUN,
               "wavelength_ratio": _fmt(self.law_ratio),
               "rmse_log_full_grey": _fmt(self.fits[GREY].errors["rmse_log"]) if GREY in self.fits else "",
               "wavelength_spread": _fmt(s.spread) if s else "", "wavelength_spread_f0": _fmt(s.spread_f0) if s else "",
               "collapse_ratio": _fmt(s.ratio) if s else "",
               "wide_samples": s.n_wide if s else 0,
               "lambda_exponent": _fmt(s.exponent) if s else "",
               "lambda_exponent_se": _fmt(s.exponent_se) if s else ""}
        return {**out, **fit_columns(self, {"rel_rmse_full": _fmt(self.fits["full"].errors.get("rel_rmse", np.nan))})}


def law_ratio(fits: dict) -> float:
    """rmse_log(full) / rmse_log(full_grey) of a material's fits (NaN without both)."""
    full, grey = fits.get("full"), fits.get(GREY)
    if full is None or grey is None or not (full.success and grey.success):
        return float("nan")
    return float(full.errors["rmse_log"] / max(grey.errors["rmse_log"], 1e-300))


def analyze_samples(samples, fits: dict, specs: dict, rule: Rule | None = None,
                    cutoff_deg: float | None = 80.0) -> SampleAnalysis:
    """Analyse one material's samples (brdfcl.data.samples.Samples) from its fits (variant key ->
    FitResult of brdfcl.optim.fit.Fitter.fit, the samples' bands; GREY: the full model fitted at
    ``grey_lambdas``) under ``rule`` (SAMPLE_RULE)."""
    rule = rule or SAMPLE_RULE
    errors = {k: r.errors["rmse_log"] for k, r in fits.items() if r.success and k in COMPARED}
    sel, pen = select(errors, {k: specs[k] for k in errors})
    lambdas = tuple(float(x) for x in samples.wavelengths)
    full = fits["full"]
    chk = spectral_check(samples, Model(specs["full"], lambdas=lambdas), full.params,
                         cutoff_deg=80.0 if cutoff_deg is None else cutoff_deg)
    m = rule.margins(float("nan"), 0, law_ratio(fits), lobe_gain(pen, specs))
    verdict = rule.verdict(m)
    free = fits.get("full_free")
    final = specs[final_key(verdict, sel, fits, specs)]
    return SampleAnalysis(samples.name, verdict, sel, final, fits, specs, pen,
                          peak_share(specs["full"], full.params, lambdas),
                          peak_share(specs["full"], free.params, lambdas) if free else float("nan"), rule=rule,
                          spectral=chk, samples=samples)
