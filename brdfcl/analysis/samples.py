"""The analysis of scattered spectral samples (a gonioreflectometer's, a Cornell ``.brdf``): the
lobe comparison and the wavelength law as for tables, the spectral curve collapse, no gradient test.

The gradient test needs the data's gradient on a regular (theta_h, theta_d) grid; scattered
samples have none, and the test run on the model fitted to them would only test the model, so it
is not run and the report says so.  The wavelength law is the tables' model comparison
(brdfcl.analysis.law): the full model fitted with each band's wavelength and with every band at
one wavelength, measured over the wide-angle samples; with tens of bands it is far sharper than on
a table's three channels.  The verdict reads the same statistic under the same thresholds as a
table's (``SAMPLE_RULE``: brdfcl.analysis.analyze.RULE without requiring the gradient test,
which is not run, so that the evidence must come from the law), so that a verdict means one thing.

The collapse of the residual band curves (brdfcl.analysis.spectral, drawn in the figure) is
reported beside it but does not decide: it subtracts a fit whose per-band diffuse level can
absorb the wavelength dependence.  The fitted exponent of lambda is reported, not used: it
assumes a spectrally flat surface reflectance, which a coloured paint is not.  On synthetic
spectral materials (tests/test_analyze_samples.py) a halo made with each band's wavelength gives
a law ratio below 0.5, the same halo made at one wavelength in every band above 2.  The lobe
comparison penalises a spectral lobe as its RGB counterpart (brdfcl.optim.selection counts
parameters on the RGB model), so that it keeps the meaning it has on tables.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from brdfcl._words import count
from brdfcl.analysis.analyze import (
    COMPARED,
    RULE,
    Analysis,
    Rule,
    _fmt,
    final_key,
    fit_columns,
    law_columns,
    lobe_gain,
    peak_share,
)
from brdfcl.analysis.law import sample_law
from brdfcl.analysis.spectral import SpectralCheck, spectral_check
from brdfcl.data.samples import Samples
from brdfcl.model.compose import Model
from brdfcl.optim.selection import select

SAMPLE_RULE = replace(RULE, gradient_required=False)
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

    def margins_raw(self) -> dict:
        ratio = self.rule.wavelength_ratio(self.law_ratio, float("nan"), self.law.colour_ratio)
        return self.rule.margins(float("nan"), 0, ratio, lobe_gain(self.penalised, self.specs))

    def row(self) -> dict:
        s = self.spectral
        out = {**self.head(),
               "data": f"{count(self.samples.n_samples, 'scattered sample')}, {count(len(self.lambdas), 'band')}",
               "gradient_test": GRADIENT_NOT_RUN,
               **law_columns(self),
               "wavelength_spread": _fmt(s.spread) if s else "", "wavelength_spread_f0": _fmt(s.spread_f0) if s else "",
               "collapse_ratio": _fmt(s.ratio) if s else "",
               "wide_samples": s.n_wide if s else 0,
               "lambda_exponent": _fmt(s.exponent) if s else "",
               "lambda_exponent_se": _fmt(s.exponent_se) if s else ""}
        return {**out, **fit_columns(self, {"rel_rmse_full": _fmt(self.fits["full"].errors.get("rel_rmse", np.nan))})}


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
    law = sample_law(fits, specs["full"], samples, cutoff_deg)
    m = rule.margins(float("nan"), 0, rule.wavelength_ratio(law.ratio, float("nan"), law.colour_ratio),
                     lobe_gain(pen, specs))
    verdict = rule.verdict(m)
    free = fits.get("full_free")
    final = specs[final_key(verdict, sel, fits, specs)]
    return SampleAnalysis(samples.name, verdict, sel, final, fits, specs, pen,
                          peak_share(specs["full"], full.params, lambdas),
                          peak_share(specs["full"], free.params, lambdas) if free else float("nan"), rule=rule,
                          law=law, spectral=chk, samples=samples)
