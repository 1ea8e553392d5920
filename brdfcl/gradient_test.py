"""The gradient test of the talk (SPEC section 5), on the measured data.

If diffraction dominates, p ~ rho_d/pi + rho_w/lambda^4 S(f), so grad p is parallel
to grad f = (2/lambda)(cos th cos td, -sin th sin td) over (theta_h, theta_d); where
Cook-Torrance dominates, the level lines follow theta_h = const (grad p along the
theta_h axis).  The two directions differ by atan(tan th tan td): the test can only
tell them apart away from the specular peak, which is why it is a wide-angle test.
It is necessary, not sufficient: at phi_d = 90 deg a Cook-Torrance lobe carries
1/(cos ti cos to) = 1/(cos^2 th cos^2 td), which tilts its level lines towards those
of f, so a broad specular lobe can pass it (brdfcl.analyze combines it with the
wavelength check and the lobe comparison).

Choices, all on the data:
* slice: the mean over phi_d in [80, 100) degrees (20 bins, where theta_i ~ theta_o),
  ignoring missing cells; its standard error is the noise of each (theta_h, theta_d) cell;
* derivatives: second-order finite differences on the actual, non-uniform bin centres
  (numpy.gradient with coordinates), so the sqrt-spaced theta_h bins need no resampling;
  a cell next to a missing one gets no gradient;
* significance: |grad p| above 3 times the propagated noise and above a 2% relative
  change per degree; below that the direction is meaningless and the cell is masked.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import bin_centres
from .merl import N_PD, N_TD, N_TH

PHI_BINS = slice(80, 100)
WIDE_TH_DEG = 5.0           # wide-angle region: theta_h at least this,
MAX_TD_DEG = 75.0           # theta_d at most this (grazing is unreliable),
MIN_SEPARATION_DEG = 10.0   # and the two hypotheses' directions differ by at least this
NOISE_K = 3.0
REL_SLOPE = 0.02            # per degree


def phi90_slice(brdf):
    """Mean (3, 90, 90) over phi_d in [80, 100) deg, its standard error, and the count."""
    t = brdf.reshape(3, N_TH, N_TD, N_PD)[..., PHI_BINS]
    n = np.isfinite(t).sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.nansum(t, axis=-1) / np.maximum(n, 1)
        var = np.nansum((t - mean[..., None]) ** 2, axis=-1) / np.maximum(n - 1, 1)
        se = np.sqrt(var / np.maximum(n, 1))
    mean[n == 0] = np.nan
    return mean, se, n


@dataclass
class GradientMap:
    """Per channel maps over (theta_h, theta_d) and the scores of the test."""

    angle_f: np.ndarray          # (3, 90, 90) degrees between grad p and grad f (lines, 0..90)
    angle_ct: np.ndarray         # (3, 90, 90) degrees between grad p and the theta_h axis
    significant: np.ndarray      # (3, 90, 90) bool: gradient above noise and flatness
    region: np.ndarray           # (90, 90) bool: wide-angle cells where the test can decide
    consistent: np.ndarray       # (3, 90, 90) bool: closer to grad f than to theta_h = const
    score: np.ndarray            # (3,) share of decidable cells consistent with diffraction
    n_cells: np.ndarray          # (3,) decidable cells per channel
    th_range_deg: list           # per channel (lo, hi) theta_h band where most cells are consistent

    @property
    def mean_score(self):
        ok = self.n_cells > 0
        return float(np.average(self.score[ok], weights=self.n_cells[ok])) if ok.any() else float("nan")


def line_angle(ax, ay, bx, by):
    """Angle in degrees between two lines (direction sign ignored)."""
    c = np.abs(ax * bx + ay * by) / np.maximum(np.hypot(ax, ay) * np.hypot(bx, by), 1e-300)
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def gradient_test(brdf) -> GradientMap:
    """Run the test on a BRDF table (3, N_CELLS) in 1/sr, NaN where missing."""
    th, td, _ = bin_centres()
    mean, se, _ = phi90_slice(brdf)
    TH, TD = np.meshgrid(th, td, indexing="ij")
    gfx, gfy = np.cos(TH) * np.cos(TD), -np.sin(TH) * np.sin(TD)
    sep = line_angle(gfx, gfy, 1.0, 0.0)
    region = (TH >= np.radians(WIDE_TH_DEG)) & (TD <= np.radians(MAX_TD_DEG)) & (sep >= MIN_SEPARATION_DEG)
    # spacing of the central differences, for the noise of a derivative
    hth = np.gradient(th)[:, None] * np.ones_like(TD)
    htd = np.gradient(td)[None, :] * np.ones_like(TH)
    shape = (3, N_TH, N_TD)
    angle_f, angle_ct = np.full(shape, np.nan), np.full(shape, np.nan)
    sig, cons = np.zeros(shape, bool), np.zeros(shape, bool)
    score, ncell, bands = np.zeros(3), np.zeros(3, int), []
    for c in range(3):
        p = mean[c]
        gth, gtd = np.gradient(p, th, td)
        gnorm = np.hypot(gth, gtd)
        noise = np.hypot(se[c] / hth, se[c] / htd) / np.sqrt(2)
        flat = REL_SLOPE * np.degrees(1.0) * np.abs(p)
        with np.errstate(invalid="ignore"):
            s = np.isfinite(gnorm) & (gnorm > NOISE_K * noise) & (gnorm > flat)
        angle_f[c] = np.where(np.isfinite(gnorm), line_angle(gth, gtd, gfx, gfy), np.nan)
        angle_ct[c] = np.where(np.isfinite(gnorm), line_angle(gth, gtd, 1.0, 0.0), np.nan)
        sig[c] = s
        decide = s & region
        cons[c] = decide & (angle_f[c] < angle_ct[c])
        ncell[c] = decide.sum()
        score[c] = cons[c].sum() / ncell[c] if ncell[c] else np.nan
        rows = [i for i in range(N_TH) if decide[i].sum() >= 3 and cons[c][i].sum() > 0.5 * decide[i].sum()]
        bands.append((float(np.degrees(th[min(rows)])), float(np.degrees(th[max(rows)]))) if rows else None)
    return GradientMap(angle_f, angle_ct, sig, region, cons, score, ncell, bands)
