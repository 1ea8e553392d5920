"""The wavelength check (docs/spec.md section 5): do the channels collapse when plotted against f_c?

Diffraction depends on the wavelength only through f_c = 2 sin th cos td / lambda_c.
In the wide-angle part of the phi_d ~ 90 deg slice, each channel's data minus its
diffuse level is binned (median) against f_c on shared log-spaced bins; each curve
is scaled by the amplitude that best matches the others (in log), and the spread
of the scaled curves is measured.  The same is done against f0 = 2 sin th cos td
(no wavelength).  If diffraction is real, the curves collapse better against f_c:
``ratio = spread(f_c) / spread(f0) < 1``.

Where the curves are power laws the check cannot decide: a power law is scale free,
so the 1/lambda shift in log f equals an amplitude change, which the per-channel
scaling removes (MERL-proxy metals sit there, ratio ~ 1).  The check therefore only
contradicts diffraction when it is decisive, ``ratio >= DECISIVE``.

``DECISIVE`` labels the check's own answer (``consistent``).  The verdict does not read the
collapse: it reads the wavelength law's model comparison (brdfcl.analysis.law), which needs no
binning or scaling; the calibration reports the collapse beside it, and the rule before the law
test read it with a veto at 5 (bench/results/calibration/calibration.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdfcl.analysis.gradient import MAX_TD_DEG, WIDE_TH_DEG, phi90_slice
from brdfcl.data.geometry import bin_centres
from brdfcl.model.lobes.diffraction import LAMBDAS

N_BINS = 24
DECISIVE = 1.5


@dataclass
class WavelengthCheck:
    edges: np.ndarray            # bin edges in f (1/um)
    curves: np.ndarray           # (3, N_BINS) median of (p - diffuse) per f_c bin, scaled
    curves_f0: np.ndarray        # (3, N_BINS) the same against f0 (bins scaled by 1/lambda_G)
    spread: float                # RMS log spread of the scaled curves against f_c
    spread_f0: float             # ... against f0
    points: tuple                # (f (3, n), q (3, n)) the samples, for plots

    @property
    def ratio(self):
        return self.spread / self.spread_f0 if self.spread_f0 > 0 else float("nan")

    @property
    def consistent(self):
        """True: collapses against f_c; False: decisively better without the wavelength; None: undecided."""
        if not np.isfinite(self.ratio):
            return None
        if self.ratio < 1.0:
            return True
        return False if self.ratio >= DECISIVE else None


def _binned(x, q, edges):
    out = np.full(len(edges) - 1, np.nan)
    k = np.digitize(x, edges) - 1
    for b in range(len(edges) - 1):
        v = q[(k == b) & (q > 0)]
        if v.size >= 5:
            out[b] = np.median(v)
    return out


def _collapse(curves):
    """Scale curves (in log) to each other over their common bins; return scaled curves, spread."""
    lc = np.log(curves)
    common = np.isfinite(lc).all(axis=0)
    if common.sum() < 3:
        return curves, float("nan")
    shift = np.mean(lc[:, common], axis=1, keepdims=True)
    lc = lc - shift
    dev = lc[:, common] - lc[:, common].mean(axis=0)
    return np.exp(lc), float(np.sqrt(np.mean(dev ** 2)))


def wavelength_check(brdf, diffuse=(0.0, 0.0, 0.0), lambdas=LAMBDAS) -> WavelengthCheck:
    th, td, _ = bin_centres()
    mean, _, _ = phi90_slice(brdf)
    TH, TD = np.meshgrid(th, td, indexing="ij")
    wide = (TH >= np.radians(WIDE_TH_DEG)) & (TD <= np.radians(MAX_TD_DEG))
    f0 = (2 * np.sin(TH) * np.cos(TD))[wide]
    q = np.stack([mean[c][wide] - diffuse[c] for c in range(3)])
    fc = np.stack([f0 / lam for lam in lambdas])
    ok = np.isfinite(q).all(axis=0)
    lo = max(np.min(fc[:, ok]), 1e-3) if ok.any() else 1e-3
    hi = np.max(fc[:, ok]) if ok.any() else 1.0
    edges = np.geomspace(lo, hi, N_BINS + 1)
    curves = np.stack([_binned(fc[c][ok], q[c][ok], edges) for c in range(3)])
    edges0 = edges * lambdas[1]
    curves0 = np.stack([_binned(f0[ok], q[c][ok], edges0) for c in range(3)])
    scaled, spread = _collapse(curves)
    scaled0, spread0 = _collapse(curves0)
    return WavelengthCheck(edges, scaled, scaled0, spread, spread0, (fc[:, ok], q[:, ok]))
