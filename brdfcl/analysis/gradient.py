"""The gradient test of the talk (docs/spec.md section 5), on the measured data.

If diffraction dominates, p ~ rho_d/pi + rho_w/lambda^4 S(f), so grad p is parallel
to grad f = (2/lambda)(cos th cos td, -sin th sin td) over (theta_h, theta_d):
``dp/dtd = -tan th tan td dp/dth``.  The talk says that where Cook-Torrance dominates
the level lines follow theta_h = const; that holds for D alone, but the CT lobe (docs/spec.md section 3)
also carries 1/(cos ti cos to), and at phi_d = 90 deg cos ti = cos to = cos th cos td
exactly, so ``dp/dtd = 2 tan td (p - rho_d/pi)`` whatever D is (D depends on theta_h
only).  Against a bare theta_h axis a pure GGX lobe scores ~0.7 (its tails tilt by
half as much as f's level lines); against this prediction it scores ~0.  Each cell is
therefore given to the hypothesis whose predicted direction, built from the measured
theta_h slope, is closer to the measured gradient.  Both lobes carry a Fresnel factor
F(td); its slope is read off the specular ridge (`ridge_log_slope`).

Choices, all on the data:
* slice: the mean over phi_d in [80, 100) degrees (20 bins, where theta_i ~ theta_o),
  ignoring missing cells; its standard error is the noise of each (theta_h, theta_d) cell;
* derivatives: second-order finite differences on the actual, non-uniform bin centres
  (numpy.gradient with coordinates), so the sqrt-spaced theta_h bins need no resampling;
  a cell next to a missing one gets no gradient;
* significance: |grad p| above 3 times the propagated noise and above a 2% relative
  change per degree; below that the direction is meaningless and the cell is masked;
* signal: the diffuse level rho_d/pi is the 2nd percentile of the slice (td <= 75 deg);
  a cell carries signal where the lobes make at least half its value (p >= 2 rho_d/pi).
  Near that floor the gradient belongs to the floor's own variation (on MERL-proxy data,
  to the network's last ReLU pieces), not to a lobe;
* decidable: wide angle (theta_h >= 5 deg, theta_d <= 75 deg, theta_i <= 80 deg), signal,
  significant, and the two predicted directions at least 10 degrees apart.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from brdfcl.data.geometry import bin_centres
from brdfcl.data.merl import N_PD, N_TD, N_TH

PHI_BINS = slice(80, 100)
WIDE_TH_DEG = 5.0           # wide-angle region: theta_h at least this,
MAX_TD_DEG = 75.0           # theta_d at most this (grazing is unreliable),
MAX_TI_DEG = 80.0           # the grazing cut-off of the fits,
MIN_SEPARATION_DEG = 10.0   # and the two hypotheses' directions differ by at least this
FLOOR_PERCENTILE = 2.0
SIGNAL_FACTOR = 2.0         # p >= this times the diffuse floor
RIDGE_BINS = 3              # theta_h bins of the specular ridge (below 0.1 deg)
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
    angle_ct: np.ndarray         # (3, 90, 90) degrees between grad p and the Cook-Torrance prediction
    significant: np.ndarray      # (3, 90, 90) bool: gradient above noise and flatness
    region: np.ndarray           # (90, 90) bool: the wide-angle region
    decidable: np.ndarray        # (3, 90, 90) bool: region, signal, significant, hypotheses apart
    consistent: np.ndarray       # (3, 90, 90) bool: closer to grad f than to the CT prediction
    floor: np.ndarray            # (3,) diffuse level of the slice (1/sr)
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


def ridge_log_slope(p, floor, td):
    """d ln (p - floor) / d theta_d along the specular ridge (the first RIDGE_BINS theta_h bins),
    smoothed over 5 theta_d bins; where the ridge is not above the floor, 2 tan td (CT with
    no Fresnel slope).  A Cook-Torrance
    lobe's log slope in theta_d is this at every theta_h (its D depends on theta_h only, and at
    phi_d = 90 deg its 1/(cos ti cos to) = 1/(cos th cos td)^2 separates), so it carries the
    Fresnel factor and the 1/cos^2 td of CT without knowing either (Smith G ~1 below the cut-off)."""
    with warnings.catch_warnings():         # a theta_d column with no ridge cell: NaN, masked below
        warnings.simplefilter("ignore", RuntimeWarning)
        ridge = np.nanmean(p[:RIDGE_BINS], axis=0) - floor
    ok = np.isfinite(ridge) & (ridge > floor)
    if ok.sum() < 10:
        return 2.0 * np.tan(td)
    lr = np.interp(td, td[ok], np.log(ridge[ok]))
    slope = np.gradient(lr, td)
    slope = np.convolve(np.pad(slope, 2, mode="edge"), np.ones(5) / 5, mode="valid")
    return np.where(td <= td[ok].max(), slope, 2.0 * np.tan(td))


def gradient_test(brdf) -> GradientMap:
    """Run the test on a BRDF table (3, N_CELLS) in 1/sr, NaN where missing."""
    th, td, _ = bin_centres()
    mean, se, _ = phi90_slice(brdf)
    TH, TD = np.meshgrid(th, td, indexing="ij")
    tan_th, tan_td = np.tan(TH), np.tan(TD)
    region = ((TH >= np.radians(WIDE_TH_DEG)) & (TD <= np.radians(MAX_TD_DEG))
              & (np.cos(TH) * np.cos(TD) >= np.cos(np.radians(MAX_TI_DEG))))
    # spacing of the central differences, for the noise of a derivative
    hth = np.gradient(th)[:, None] * np.ones_like(TD)
    htd = np.gradient(td)[None, :] * np.ones_like(TH)
    shape = (3, N_TH, N_TD)
    angle_f, angle_ct = np.full(shape, np.nan), np.full(shape, np.nan)
    sig, dec, cons = np.zeros(shape, bool), np.zeros(shape, bool), np.zeros(shape, bool)
    score, ncell, floor, bands = np.full(3, np.nan), np.zeros(3, int), np.zeros(3), []
    for c in range(3):
        p = mean[c]
        ok = np.isfinite(p) & (TD <= np.radians(MAX_TD_DEG))
        floor[c] = max(np.percentile(p[ok], FLOOR_PERCENTILE), 0.0) if ok.any() else 0.0
        gth, gtd = np.gradient(p, th, td)
        gnorm = np.hypot(gth, gtd)
        noise = np.hypot(se[c] / hth, se[c] / htd) / np.sqrt(2)
        flat = REL_SLOPE * np.degrees(1.0) * np.abs(p)
        # The hypotheses' gradients given the measured theta_h slope.  Both lobes share F(td);
        # its slope comes from the specular ridge, read as Cook-Torrance's (the talk: the peak is
        # CT) or as diffraction's (no peak lobe); diffraction may take either reading.
        lobe = p - floor[c]
        ridge = ridge_log_slope(mean[c], floor[c], td)[None, :]
        cx, cy = gth, ridge * lobe
        wy = -tan_th * tan_td * gth
        w_ct, w_pure = wy + (ridge - 2.0 * tan_td) * lobe, wy + ridge * lobe
        with np.errstate(invalid="ignore"):
            s = np.isfinite(gnorm) & (gnorm > NOISE_K * noise) & (gnorm > flat)
            signal = p >= SIGNAL_FACTOR * floor[c]
            apart = np.minimum(line_angle(gth, w_ct, cx, cy), line_angle(gth, w_pure, cx, cy)) >= MIN_SEPARATION_DEG
            angle_w = np.minimum(line_angle(gth, gtd, gth, w_ct), line_angle(gth, gtd, gth, w_pure))
        angle_f[c] = np.where(np.isfinite(gnorm), line_angle(gth, gtd, np.cos(TH) * np.cos(TD),
                                                             -np.sin(TH) * np.sin(TD)), np.nan)
        angle_ct[c] = np.where(np.isfinite(gnorm), line_angle(gth, gtd, cx, cy), np.nan)
        sig[c] = s
        dec[c] = s & region & signal & apart
        cons[c] = dec[c] & (angle_w < angle_ct[c])
        ncell[c] = dec[c].sum()
        if ncell[c]:
            score[c] = cons[c].sum() / ncell[c]
        rows = [i for i in range(N_TH) if dec[c][i].sum() >= 3 and cons[c][i].sum() > 0.5 * dec[c][i].sum()]
        bands.append((float(np.degrees(th[min(rows)])), float(np.degrees(th[max(rows)]))) if rows else None)
    return GradientMap(angle_f, angle_ct, sig, region, dec, cons, floor, score, ncell, bands)
