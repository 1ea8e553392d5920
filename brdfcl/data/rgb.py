"""Spectral samples to linear sRGB samples, for users who want an RGB model of a spectral
measurement (needs the ``colour`` package, colour-science).

Conversion (one 3 x C matrix applied to every sample's spectrum):

* The spectrum ``v(lambda)`` given at the channel wavelengths (BRDF in 1/sr) is read as a
  reflectance-like spectrum: linear between the channel wavelengths, constant beyond the first
  and the last (colour's default extrapolation).
* It is integrated against the illuminant ``S(lambda)`` (CIE D65 by default, any name of
  ``colour.SDS_ILLUMINANTS``) times the CIE 1931 2 degree colour-matching functions, 360 to 780
  nm in 1 nm steps, giving XYZ, then mapped to linear sRGB by the IEC 61966-2-1 XYZ -> RGB
  matrix (no transfer function: BRDF values stay linear).
* Each RGB row is normalised so that a spectrally flat BRDF of value v gives (v, v, v): the
  units stay 1/sr and an achromatic surface stays grey.  Under D65 this is a correction of
  < 0.02 % (sRGB's white is D65), and compensates the spectrum's truncated range; under another
  illuminant it is a white balance in linear sRGB (a von Kries scaling on sRGB primaries, not a
  full chromatic adaptation).
* Out-of-gamut spectra give negative components; they are kept, not clipped (clipping would bias
  the fit).  NaN (missing) in any band gives NaN in all three channels.

Effective wavelengths.  The diffraction lobe needs one wavelength per channel.  A channel's
value is ``sum_lambda r_c(lambda) v(lambda)`` with a response ``r_c`` normalised to sum 1; its
first moment ``lambda_c = sum lambda r_c(lambda)`` is the wavelength at which the channel samples
any spectrum that varies linearly with wavelength exactly, so that is the effective wavelength
(``effective_wavelengths``).  Under D65: R 0.642, G 0.543, B 0.441 um, against the 0.645, 0.526,
0.444 um used for MERL tables (R and B agree within 0.003 um, G is 0.017 um longer).  The mean
over the positive part of each response alone would give 0.600, 0.539, 0.453 um.  ``to_rgb``
labels its channels with the MERL wavelengths by default, so that a converted measurement is
fitted exactly like a MERL table; ``effective=True`` labels them with the computed ones.
"""
from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from typing import TypeVar, cast

import numpy as np

from .measurement import Measurement
from .samples import RGB_WAVELENGTHS_UM, Channel, Samples

M = TypeVar("M", bound=Measurement)

OBSERVER = "CIE 1931 2 Degree Standard Observer"
COLOURSPACE = "sRGB"
RANGE_NM = (360, 780)


def _colour():
    try:
        import colour
    except ImportError as e:          # an optional dependency: say which package to install
        raise ImportError("spectral to RGB conversion needs colour-science: pip install colour-science") from e
    return colour


@lru_cache(maxsize=16)
def _responses(illuminant: str) -> tuple[np.ndarray, np.ndarray]:
    """(wavelengths nm (L,), un-normalised linear sRGB responses (L, 3) = S * (M @ cmf))."""
    colour = _colour()
    if illuminant not in colour.SDS_ILLUMINANTS:
        raise ValueError(f"unknown illuminant {illuminant!r}: use a name of colour.SDS_ILLUMINANTS (D65, D50, A, E...)")
    shape = colour.SpectralShape(RANGE_NM[0], RANGE_NM[1], 1)
    cmfs = colour.MSDS_CMFS[OBSERVER].copy().align(shape)
    s = colour.SDS_ILLUMINANTS[illuminant].copy().align(shape).values
    m = np.asarray(colour.RGB_COLOURSPACES[COLOURSPACE].matrix_XYZ_to_RGB, dtype=np.float64)
    r = (np.asarray(cmfs.values, dtype=np.float64) @ m.T) * np.asarray(s, dtype=np.float64)[:, None]
    return np.asarray(cmfs.wavelengths, dtype=np.float64), r


def effective_wavelengths(illuminant: str = "D65") -> tuple[float, float, float]:
    """First moments (um) of the R, G, B responses under the illuminant (see module docstring)."""
    wl, r = _responses(illuminant)
    lam = (wl[:, None] * r).sum(axis=0) / r.sum(axis=0) / 1000.0
    return float(lam[0]), float(lam[1]), float(lam[2])


def rgb_matrix(wavelengths_um: np.ndarray, illuminant: str = "D65") -> np.ndarray:
    """(3, C) matrix taking a spectrum at these wavelengths to linear sRGB, rows summing to 1."""
    wl_nm = 1000.0 * np.asarray(wavelengths_um, dtype=np.float64)
    if wl_nm.ndim != 1 or wl_nm.size == 0:
        raise ValueError("need at least one wavelength")
    if wl_nm.max() < RANGE_NM[0] or wl_nm.min() > RANGE_NM[1]:
        raise ValueError(f"no wavelength in the visible range {RANGE_NM[0]}-{RANGE_NM[1]} nm: cannot make RGB")
    grid, r = _responses(illuminant)
    order = np.argsort(wl_nm)
    basis = np.empty((grid.size, wl_nm.size))
    for j, k in enumerate(order):                        # hat function of channel k on the grid
        basis[:, k] = np.interp(grid, wl_nm[order], np.eye(wl_nm.size)[j])
    k_mat = r.T @ basis                                  # (3, C)
    return k_mat / k_mat.sum(axis=1, keepdims=True)


def to_rgb(samples: M, illuminant: str = "D65", *, effective: bool = False) -> M:
    """Linear sRGB samples of a spectral measurement (same directions and weights).

    Channels are R, G, B with the MERL wavelengths 0.645, 0.526, 0.444 um, or with
    ``effective_wavelengths(illuminant)`` if ``effective``.  A measurement already in R, G, B (a
    MERL table) is returned as it is; ValueError for another measurement that is not scattered
    samples."""
    if tuple(c.name for c in samples.channels) == tuple(RGB_WAVELENGTHS_UM):
        return samples
    if not isinstance(samples, Samples):
        raise ValueError(f"{samples.path or samples.name}: only scattered spectral samples convert to RGB")
    k_mat = rgb_matrix(samples.wavelengths, illuminant)
    values = samples.values @ k_mat.T
    lams = effective_wavelengths(illuminant) if effective else tuple(RGB_WAVELENGTHS_UM.values())
    channels = tuple(Channel(n, lam) for n, lam in zip(RGB_WAVELENGTHS_UM, lams))
    return cast(M, replace(samples, values=values, channels=channels))
