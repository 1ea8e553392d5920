"""The wavelength law by model comparison: one test and one statistic for tables and samples.

Diffraction depends on the wavelength only through f_c = 2 sin th cos td / lambda_c: each
channel's halo is the same curve at a frequency scaled by 1/lambda_c.  The test fits the full
model twice to the same cells, from the same two global searches (with and without the peak
constraint there; the better fit kept), so that neither side gets more tries: once with each
channel's own wavelength, and once with every channel at the middle channel's wavelength
(``grey_lambdas``: the same parameters, scattering that ignores the wavelength).  Both fits are
then measured where the law makes its prediction, the wide-angle region of the gradient test
(theta_h >= 5 deg, theta_d <= 75 deg, theta_i and theta_o <= 80 deg), in relative terms:

    law_ratio = E(lambda_c) / E(one lambda),  E = RMS over the region of ln(fit / measured),

below 1 where the wavelength enters as diffraction predicts.  The fits' own error (rmse_log, of
ln(1 + f cos theta_i)) hardly weighs the small values there: on synthetic halos carrying half of
the wide-angle energy under 2% noise it moved by 0.1-1.5% between the two fits where E moved by
10-85%.  The statistic uses every region cell (every WIDE_STRIDE-th of a table) and needs no
binning, so no per-channel amplitude scaling removes the signal (the curve collapse of
brdfcl.analysis.wavelength does, and stays as the picture of the law).  Where the halo is a
power law the two fits are equally good (a power law is scale free: the 1/lambda shift equals an
amplitude change, which each channel's own amplitude absorbs) and the ratio stays near 1: the
test cannot decide there, and the verdict's threshold (brdfcl.analysis.analyze.Rule) says how far
below 1 it must be.

Beside it the same comparison on the colour alone: ``colour_ratio`` = C(lambda_c) / C(one lambda),
C the RMS of each channel's log residual minus the mean of the channels' at that cell.  A misfit
that the channels share (a halo shape the model's power spectrum cannot follow, a sheen it has no
lobe for) cancels there, and what remains is how the colour varies over the angles, which is what
the law predicts; it is reported and calibrated beside ``law_ratio``.

Materials whose colour changes with angle for other reasons (thin films, dispersion of a metal's
Fresnel term, a roughness per channel) can move either ratio either way: the calibration
(brdfcl.analysis.calibration) measures them as no-diffraction classes.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from brdfcl.analysis.gradient import MAX_TD_DEG, MAX_TI_DEG, WIDE_TH_DEG
from brdfcl.data.geometry import table_geometry
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.optim.fit import Fitter

GREY = "full_grey"            # the fit key of the full model with every channel at one wavelength
GREY_STEP = 1e-5              # the grey channels' relative offsets, so that their names stay distinct
WIDE_STRIDE = 5               # a table's wide-angle cells: every n-th (about 140 000 of them)


def _ratio(a: float, b: float) -> float:
    if not (np.isfinite(a) and np.isfinite(b)) or b < 0:
        return float("nan")
    if b == 0:
        return float("inf") if a > 0 else float("nan")
    return float(a / b)


@dataclass(frozen=True)
class LawTest:
    """The two fits' errors in the wide-angle region (``wide_error``) and their ratios."""

    error: float                 # E of the full model with each channel's wavelength
    error_grey: float            # E of the full model with every channel at one wavelength
    n_cells: int                 # region cells (or samples) with a measured value
    colour: float = float("nan")        # C of the full model with each channel's wavelength
    colour_grey: float = float("nan")   # C with every channel at one wavelength

    @property
    def ratio(self) -> float:
        """``law_ratio``: below 1, the wavelength enters as diffraction predicts (NaN: no test)."""
        return _ratio(self.error, self.error_grey)

    @property
    def colour_ratio(self) -> float:
        """``colour_ratio``: the same on the colour alone (NaN: no test, or a single channel)."""
        return _ratio(self.colour, self.colour_grey)


NO_TEST = LawTest(float("nan"), float("nan"), 0)


def grey_lambdas(lambdas) -> tuple:
    """Every channel at the middle channel's wavelength (channel i offset by i x GREY_STEP
    relative, which moves f by at most 1e-3 for 100 bands and keeps spectral channel names
    distinct at any wavelength): the wavelength law of scattering that ignores the wavelength."""
    mid = float(lambdas[len(lambdas) // 2])
    return tuple(mid * (1.0 + GREY_STEP * i) for i in range(len(lambdas)))


@lru_cache(maxsize=2)
def wide_cells(stride: int = WIDE_STRIDE):
    """(Cells, table indices, measure x cos theta_i) of a table's wide-angle region, every
    ``stride``-th cell: where the gradient test looks and the law is measured."""
    g = table_geometry()
    cut = np.cos(np.radians(MAX_TI_DEG))
    ok = (g.above_horizon & (g.theta_h >= np.radians(WIDE_TH_DEG)) & (g.theta_d <= np.radians(MAX_TD_DEG))
          & (g.cos_i >= cut) & (g.cos_o >= cut))
    idx = np.flatnonzero(ok)[::stride]
    return Cells.from_geometry(g, idx), idx, g.weight[idx] * g.cos_i[idx]


def wide_samples(samples, cutoff_deg: float | None = MAX_TI_DEG) -> np.ndarray:
    """The mask of scattered samples (brdfcl.data.samples.Samples) in the same region, within the
    fit's angle cut-off."""
    th, td, _ = samples.isotropic()
    cut = MAX_TI_DEG if cutoff_deg is None else min(cutoff_deg, MAX_TI_DEG)
    return samples.mask(cut) & (th >= np.radians(WIDE_TH_DEG)) & (td <= np.radians(MAX_TD_DEG))


def wide_error(model: Model, params: dict, cells: Cells, values: np.ndarray) -> tuple[float, int, float]:
    """(E, cells used, C): E the RMS over ``cells`` of ln(model / measured) where both are positive;
    C the RMS of those residuals minus their mean over the channels, at the cells where every
    channel has one (NaN for a single channel); ``values`` (C, n) the measured values there (NaN:
    missing)."""
    p = model.reference(cells, model.only_lobes(params, None), jacobian=False)
    ok = np.isfinite(values) & (values > 0) & (p > 0)
    if not ok.any():
        return float("nan"), 0, float("nan")
    r = np.log(np.where(ok, p, 1.0) / np.where(ok, values, 1.0))
    every = ok.all(axis=0)
    e = float(np.sqrt(np.mean(r[ok] ** 2)))
    if r.shape[0] < 2 or not every.any():
        return e, int(every.sum()), float("nan")
    d = r[:, every] - r[:, every].mean(axis=0)
    return e, int(every.sum()), float(np.sqrt(np.mean(d * d)))


def law_test(fits: dict, spec: str, lambdas, cells: Cells, values: np.ndarray) -> LawTest:
    """The law of one material from its fits (``full`` at ``lambdas``, ``GREY`` at
    ``grey_lambdas``; NO_TEST without both) measured at ``cells`` ((C, n) ``values``)."""
    full, grey = fits.get("full"), fits.get(GREY)
    if full is None or grey is None or not (full.success and grey.success):
        return NO_TEST
    e, n, c = wide_error(Model(spec, lambdas=tuple(lambdas)), full.params, cells, values)
    e_grey, _, c_grey = wide_error(Model(spec, lambdas=grey_lambdas(lambdas)), grey.params, cells, values)
    return LawTest(e, e_grey, n, c, c_grey)


def table_law(fits: dict, spec: str, lambdas, brdf: np.ndarray) -> LawTest:
    """``law_test`` on a table's wide-angle cells (``wide_cells``); ``brdf`` (C, N_CELLS)."""
    cells, idx, _ = wide_cells()
    return law_test(fits, spec, lambdas, cells, brdf[:, idx])


def sample_law(fits: dict, spec: str, samples, cutoff_deg: float | None = MAX_TI_DEG) -> LawTest:
    """``law_test`` on a material's wide-angle samples (``wide_samples``), at their bands."""
    wide = wide_samples(samples, cutoff_deg)
    if not wide.any():
        return NO_TEST
    cells = Cells.from_directions(samples.wi[wide], samples.wo[wide])
    values = np.asarray(samples.values[wide], dtype=float).T
    return law_test(fits, spec, tuple(float(x) for x in samples.wavelengths), cells, values)


def grey_fitters(full, lambdas, ct_peak: bool) -> dict:
    """The law's rival fitters beside the full model's Fitter ``full`` (brdfcl.optim.fit), whose
    channels are at ``lambdas``: ``GREY`` with the full model's options at ``grey_lambdas``, and
    with the peak constraint ``GREY + "_local"`` from a global search without it (as the full
    model's ``full_local``), sharing GREY's engine."""
    grey = grey_lambdas(lambdas)
    out = {GREY: Fitter(full.opts, lambdas=grey)}
    if ct_peak:
        out[GREY + "_local"] = Fitter(replace(full.opts, ct_peak_global=False), engine=out[GREY].engine,
                                      lambdas=grey)
    return out
