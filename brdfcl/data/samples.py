"""One measured material given as scattered samples: directions x channels x weights.

A MERL table is a fixed grid of (theta_h, theta_d, phi_d) cells; gonioreflectometers measure at
whatever directions they reach, often at many wavelengths.  ``Samples`` holds such a measurement
as it is (never resampled onto a grid): the two directions of each sample, one BRDF value per
channel, each channel's wavelength (what the diffraction lobe needs) and each sample's weight
(the measure of the (wi, wo) domain it stands for, ``weights.sample_weights``), so that fits and
error metrics mean the same thing as on a table.
"""
from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from .errors import DataError
from .measurement import RGB_WAVELENGTHS_UM, Channel, Layout, Measurement, cell_rows, rgb_channels
from .weights import sample_weights

DEFAULT_CUTOFF_DEG = 80.0
"""Default angle cut-off of ``Samples.mask``, the same as for MERL tables' cells."""

_ANGLE_TOL = 1e-5          # radians: files round angles (Cornell's 1.570796 for pi/2)


def _frozen(a: ArrayLike, ndim: int) -> np.ndarray:
    out = np.array(a, dtype=np.float64, copy=True)
    if out.ndim != ndim:
        raise ValueError(f"expected a {ndim}D array, got shape {out.shape}")
    out.setflags(write=False)
    return out


__all__ = ["DEFAULT_CUTOFF_DEG", "RGB_WAVELENGTHS_UM", "Channel", "SampleLayout", "Samples", "make_samples",
           "rgb_channels"]


class SampleLayout(Layout):
    """The cells of one scattered measurement: its samples, in file order; few enough that every
    stage of a fit uses all of them (not ``dense``)."""

    def __init__(self, samples: Samples):
        self.samples = samples
        self._weights: dict = {}

    def select(self, cutoff_deg: float | None = DEFAULT_CUTOFF_DEG) -> np.ndarray:
        return np.flatnonzero(self.samples.mask(cutoff_deg))

    def weights(self, index: np.ndarray, cutoff_deg: float | None = DEFAULT_CUTOFF_DEG) -> np.ndarray:
        """``Samples.weights_within`` the cut-off (computed once per cut-off)."""
        if cutoff_deg not in self._weights:
            self._weights[cutoff_deg] = self.samples.weights_within(cutoff_deg)
        return np.asarray(self._weights[cutoff_deg][index], dtype=np.float64)

    def rows(self, index: np.ndarray) -> tuple[np.ndarray, ...]:
        return cell_rows(self.samples.wi[index], self.samples.wo[index])


@dataclass(frozen=True, eq=False)
class Samples(Measurement):
    """Scattered samples of one material.  Arrays are float64 and read-only.

    Angles in radians, normal = +z, ``phi`` measured in one frame for both directions (so
    ``phi_o = phi_i + pi`` is the plane of incidence on the specular side).  ``values`` (n, C)
    is the BRDF in 1/sr, NaN where missing; ``weights`` (n,) the measure (sr^2) of the whole
    (wi, wo) domain each sample stands for (``weights_within`` for a fit with a cut-off)."""

    name: str
    path: str | None
    theta_i: np.ndarray
    phi_i: np.ndarray
    theta_o: np.ndarray
    phi_o: np.ndarray
    values: np.ndarray
    channels: tuple[Channel, ...]
    weights: np.ndarray

    def __post_init__(self) -> None:
        for f in ("theta_i", "phi_i", "theta_o", "phi_o", "weights"):
            object.__setattr__(self, f, _frozen(getattr(self, f), 1))
        object.__setattr__(self, "values", _frozen(self.values, 2))
        object.__setattr__(self, "channels", tuple(self.channels))
        n = self.theta_i.size
        if not (self.phi_i.size == self.theta_o.size == self.phi_o.size == self.weights.size == n):
            raise ValueError("angle and weight arrays must have one entry per sample")
        if self.values.shape != (n, len(self.channels)):
            raise ValueError(f"values shape {self.values.shape}: expected ({n}, {len(self.channels)})")
        if len({c.name for c in self.channels}) != len(self.channels):
            raise ValueError("channel names must be distinct")

    @property
    def n_samples(self) -> int:
        return int(self.theta_i.size)

    @cached_property
    def layout(self) -> SampleLayout:
        return SampleLayout(self)

    def values_at(self, indices, outs) -> None:
        for o, idx in zip(outs, indices):
            o[...] = self.values[idx].T

    @cached_property
    def wi(self) -> np.ndarray:
        """Incident unit vectors (n, 3)."""
        return _unit(self.theta_i, self.phi_i)

    @cached_property
    def wo(self) -> np.ndarray:
        """Outgoing unit vectors (n, 3)."""
        return _unit(self.theta_o, self.phi_o)

    @property
    def cos_i(self) -> np.ndarray:
        return self.wi[:, 2]

    @property
    def cos_o(self) -> np.ndarray:
        return self.wo[:, 2]

    @property
    def above_horizon(self) -> np.ndarray:
        """theta_i and theta_o below 90 deg (a grazing sample at exactly 90 deg is not above)."""
        return (self.theta_i < 0.5 * np.pi) & (self.theta_o < 0.5 * np.pi)

    def mask(self, cutoff_deg: float | None = DEFAULT_CUTOFF_DEG) -> np.ndarray:
        """Samples above the horizon with theta_i and theta_o below the cut-off (None: 90 deg),
        the rule of a MERL table's cells."""
        if cutoff_deg is None or cutoff_deg >= 90:
            return self.above_horizon
        if not 0 < cutoff_deg <= 90:
            raise ValueError(f"angle cut-off {cutoff_deg} deg: must be in (0, 90]")
        c = np.cos(np.radians(cutoff_deg))
        return self.above_horizon & (self.cos_i > c) & (self.cos_o > c)

    def weights_within(self, cutoff_deg: float | None = DEFAULT_CUTOFF_DEG) -> np.ndarray:
        """The sample-weight rule on the domain a fit with this angle cut-off uses (theta_i,
        theta_o below it; zero for samples beyond): weights to pair with ``mask(cutoff_deg)``.

        ``weights`` cover the whole domain, so samples at the edge of the cut-off also stand for
        the grazing band beyond it; a MERL table's masked cells do not.  (Krylon: the theta_i =
        80 deg samples carry 32 % of ``weights`` but 7 % of ``weights_within(80)``.)  Computed on
        each call from the angles (0.3 s for 1439 samples)."""
        return sample_weights(self.theta_i, self.phi_i, self.theta_o, self.phi_o,
                              cutoff_deg=None if cutoff_deg is None or cutoff_deg >= 90 else cutoff_deg)

    def isotropic(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rusinkiewicz angles (theta_h, theta_d, phi_d) of each sample, as MERL indexes them.

        h = (wi + wo) / |wi + wo|; d is wi in the frame where h has phi_h = 0 and lies in the
        xz plane (d = Ry(-theta_h) Rz(-phi_h) wi).  phi_d is folded into [0, pi): reciprocity
        (wi <-> wo) turns d into -d, phi_d into phi_d + pi."""
        wi, wo = self.wi, self.wo
        h = wi + wo
        h = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
        theta_h = np.arctan2(np.hypot(h[:, 0], h[:, 1]), h[:, 2])
        phi_h = np.arctan2(h[:, 1], h[:, 0])
        cp, sp = np.cos(phi_h), np.sin(phi_h)
        x = cp * wi[:, 0] + sp * wi[:, 1]                       # Rz(-phi_h) wi
        y = -sp * wi[:, 0] + cp * wi[:, 1]
        z = wi[:, 2]
        ct, st = np.cos(theta_h), np.sin(theta_h)
        x, z = ct * x - st * z, st * x + ct * z                 # Ry(-theta_h)
        theta_d = np.arctan2(np.hypot(x, y), z)
        phi_d = np.mod(np.arctan2(y, x), np.pi)
        phi_d[phi_d >= np.pi] = 0.0                             # mod can round up to pi
        return theta_h, theta_d, phi_d


def _unit(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    st = np.sin(theta)
    out = np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=1)
    out.setflags(write=False)
    return out


def make_samples(path: str | os.PathLike[str] | None, theta_i: ArrayLike, phi_i: ArrayLike,
                 theta_o: ArrayLike, phi_o: ArrayLike, values: ArrayLike, channels: Sequence[Channel], *,
                 name: str | None = None, lines: Sequence[int] | None = None,
                 weights: ArrayLike | None = None) -> Samples:
    """Samples from a file's numbers, checked as a file: DataError naming the file (and the
    line, ``lines[j]`` for sample j) for no samples, angles out of range or non-finite values.

    Angles in radians: theta in [0, pi/2] (rounding of 1e-5 rad tolerated and clipped), phi in
    [-2 pi, 2 pi].  Weights default to ``sample_weights`` of the angles."""
    ti, pi_, to, po = (np.asarray(a, dtype=np.float64).ravel() for a in (theta_i, phi_i, theta_o, phi_o))
    v = np.asarray(values, dtype=np.float64)
    channels = tuple(channels)
    if name is None:
        name = "samples" if path is None else os.path.splitext(os.path.basename(os.fspath(path)))[0]
    if ti.size == 0:
        raise DataError(path, "no samples")
    if v.ndim != 2 or v.shape != (ti.size, len(channels)):
        raise DataError(path, f"values of shape {v.shape}: expected ({ti.size}, {len(channels)})")

    def fail(j: int, problem: str) -> DataError:
        return DataError(path, problem, None if lines is None else lines[j])

    for label, a, lo, hi in (("theta_i", ti, 0.0, 0.5 * np.pi), ("theta_o", to, 0.0, 0.5 * np.pi),
                             ("phi_i", pi_, -2 * np.pi, 2 * np.pi), ("phi_o", po, -2 * np.pi, 2 * np.pi)):
        bad = np.flatnonzero(~np.isfinite(a) | (a < lo - _ANGLE_TOL) | (a > hi + _ANGLE_TOL))
        if bad.size:
            x = a[bad[0]]
            raise fail(bad[0], f"{label} = {np.degrees(x):.6g} deg ({x:.6g} rad) is out of range "
                               f"[{np.degrees(lo):g}, {np.degrees(hi):g}] deg")
    bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
    if bad.size:
        raise fail(bad[0], "value is NaN or infinite: values must be finite numbers")
    names = [c.name for c in channels]
    if len(set(names)) != len(names):
        raise DataError(path, f"repeated channel {next(x for x in names if names.count(x) > 1)!r}")
    ti, to = (np.clip(a, 0.0, 0.5 * np.pi) for a in (ti, to))
    w = sample_weights(ti, pi_, to, po) if weights is None else np.asarray(weights, dtype=np.float64)
    return Samples(name, None if path is None else os.fspath(path), ti, pi_, to, po, v, channels, w)
