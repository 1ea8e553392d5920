"""The wavelength check on spectral samples: does the wide-angle scattering of every band collapse
against f = 2 sin th cos td / lambda, and which power of lambda scales it?

Diffraction by a surface whose heights have the power spectrum S predicts, outside the specular
peak, ``p_c = K lambda_c^-4 S(f0 / lambda_c)``, f0 = 2 sin th cos td (Holzschuch & Pacanowski,
after Church & Takacs).  With tens of bands this can be tested far more sharply than with three
RGB channels.  Given a fit of the full model to the samples (one wavelength per band):

* collapse: in the wide-angle region, the data minus the fitted diffuse and reflection lobes (what
  is left for diffraction), binned (median) against f_c on shared log bins and scaled per band,
  spreads less against f_c than against f0 when the wavelength enters through f:
  ``ratio = spread(f_c) / spread(f0) < 1`` (brdfcl.analysis.wavelength does the same on a MERL
  table's three channels);
* exponent: the fitted diffraction amplitude of band c is ``rho_c lambda_c^-4``; if the surface's
  reflectance is flat over the spectrum (dielectric overcoats, paints; not coloured metals),
  ``rho_c`` is the same in every band, and the power of lambda is ``n = 4 - d ln rho / d ln lambda``
  (weighted least squares over the bands); diffraction predicts n = 4.

A MERL table cannot give the exponent: three channels with a free amplitude each leave no slope
to speak of.  The gradient test needs a regular grid of theta_h and theta_d and is not run on
scattered samples (a test on the model fitted to them would be no evidence).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdfcl.analysis.law import wide_samples
from brdfcl.analysis.wavelength import DECISIVE, N_BINS, _binned, _collapse
from brdfcl.model.lobes.cells import Cells

THEORY_EXPONENT = 4.0
MIN_SAMPLES = 30             # wide-angle samples below which the check says nothing


@dataclass
class SpectralCheck:
    """What the two tests found on one material's samples."""

    wavelengths: np.ndarray      # (C,) um
    n_wide: int                  # wide-angle samples used
    spread: float                # RMS log spread of the scaled band curves against f_c
    spread_f0: float             # ... against f0
    exponent: float              # n of lambda^-n from the fitted per-band diffraction amplitudes
    exponent_se: float           # its standard error (from the scatter of the bands about the line)
    points: tuple                # (f0 (n,), q (C, n)): wide-angle data minus diffuse and reflection
    edges: np.ndarray            # bin edges in f (1/um)
    curves: np.ndarray           # (C, N_BINS) scaled band curves against f_c
    curves_f0: np.ndarray        # (C, N_BINS) ... against f0, on the bins edges * the middle band's lambda

    @property
    def ratio(self) -> float:
        return self.spread / self.spread_f0 if self.spread_f0 > 0 else float("nan")

    @property
    def consistent(self) -> bool | None:
        """True: collapses against f_c; False: decisively better without the wavelength; None:
        undecided (as brdfcl.analysis.wavelength.WavelengthCheck)."""
        if not np.isfinite(self.ratio):
            return None
        if self.ratio < 1.0:
            return True
        return False if self.ratio >= DECISIVE else None


def lambda_exponent(model, params) -> tuple[float, float]:
    """(n, standard error) of lambda^-n from a fit's per-band diffraction amplitudes: the slope of
    ln(rho_c lambda_c^-4) against ln(lambda_c), weighted by each band's share of the amplitude."""
    lam = np.asarray(model.lambdas, dtype=float)
    rho = np.zeros(lam.size)
    for pre in model.prefixes_with_role("diffraction"):
        rho += np.array([params[f"{pre}.rho_{c}"] for c in model.channels])
    ok = rho > 0
    if ok.sum() < 3:
        return float("nan"), float("nan")
    x, y = np.log(lam[ok]), np.log(rho[ok]) - 4 * np.log(lam[ok])
    w = rho[ok] / rho[ok].sum()
    X = np.stack([np.ones_like(x), x], axis=1)
    W = np.diag(w)
    cov = np.linalg.inv(X.T @ W @ X)
    beta = cov @ X.T @ W @ y
    r = y - X @ beta
    dof = max(ok.sum() - 2, 1)
    s2 = float(np.sum(w * r * r) / (np.sum(w) * dof / ok.sum()))
    return float(-beta[1]), float(np.sqrt(cov[1, 1] * s2))


def spectral_check(samples, model, params, cutoff_deg: float = 80.0) -> SpectralCheck | None:
    """Both tests on one material's samples (brdfcl.data.samples.Samples) given the full model
    fitted to them (``params``: {name: value}); None when fewer than MIN_SAMPLES samples are
    wide-angle (theta_h >= WIDE_TH_DEG, theta_d <= MAX_TD_DEG) or fewer than three bands."""
    th, td, _ = samples.isotropic()
    wide = wide_samples(samples, cutoff_deg)
    lam = np.asarray(samples.wavelengths, dtype=float)
    if wide.sum() < MIN_SAMPLES or lam.size < 3:
        return None
    cells = Cells.from_directions(samples.wi[wide], samples.wo[wide])
    others = model.prefixes_with_role("diffuse", "reflection")
    rest = model.reference(cells, model.only_lobes(params, others), jacobian=False)
    f0 = 2 * np.sin(th[wide]) * np.cos(td[wide])
    q = np.asarray(samples.values[wide], dtype=float).T - rest
    fc = f0[None] / lam[:, None]
    good = np.isfinite(q).all(axis=0)
    edges = np.geomspace(max(np.min(fc[:, good]), 1e-3), np.max(fc[:, good]), N_BINS + 1)
    curves = np.stack([_binned(fc[c][good], q[c][good], edges) for c in range(lam.size)])
    curves0 = np.stack([_binned(f0[good], q[c][good], edges * lam[lam.size // 2]) for c in range(lam.size)])
    scaled, spread = _collapse(curves)
    scaled0, spread0 = _collapse(curves0)
    n, se = lambda_exponent(model, params)
    return SpectralCheck(lam, int(wide.sum()), spread, spread0, n, se, (f0, q), edges, scaled, scaled0)
