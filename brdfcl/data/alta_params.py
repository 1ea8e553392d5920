"""ALTA's input parametrisations: how a row's coordinates give its two directions (n = z).

ALTA converts every parametrisation through ``CARTESIAN``, the pair (view, light) of unit
vectors; brdfcl reads the same pair as (wi, wo): its models are isotropic and reciprocal, so
which of the two is the light does not matter, nor does a mirror image ``y -> -y``.  Angles are
radians.  The conventions, as ALTA's own conversion to ``CARTESIAN`` places the directions:

* ``RUSIN_TH_PH_TD_PD`` (theta_h, phi_h, theta_d, phi_d): Rusinkiewicz's half and difference
  angles; the first direction is d = (theta_d, phi_d) rotated by theta_h about y, then by phi_h
  about z, the second its mirror about h.  ``RUSIN_TH_TD_PD`` is the same with phi_h = 0;
  ``RUSIN_TH_TD`` with phi_h = 0 and phi_d = pi/2; ``COS_TH_TD`` (cos theta_h, cos theta_d) with
  phi_h = phi_d = 0.
* ``COS_TH`` (cos theta_h): a one-dimensional slice, placed as ALTA places it: theta_d = 0,
  phi_h = phi_d = 0, so both directions are h itself (wi = wo, the backscattering direction at
  theta = theta_h in the plane phi = 0).  A 1-D slice defines directions only under this
  convention; a file made from another slice of (theta_h, theta_d, phi_d) is read as if it were
  this one.
* ``ISOTROPIC_TV_TL_DPHI`` (theta_v, theta_l, dphi): the view at (theta_v, 0), the light at
  (theta_l, dphi).  ``SPHERICAL_TL_PL_TV_PV``: both in spherical coordinates, light first.
* ``ISOTROPIC_TL_TV_PROJ_DPHI`` (theta_l, x, y): the light at (theta_l, phi = 0); the view's
  azimuth relative to the light projected onto the plane, (x, y) = theta_v (cos dphi, sin dphi),
  so theta_v = |(x, y)| and dphi = atan2(y, x).  x > 0 puts the view on the light's side (x =
  theta_l, y = 0 is the retro-reflection direction, view = light); x < 0 on the opposite side
  (x = -theta_l, y = 0 is the mirror direction).  The sign of y is a mirror image (ALTA's
  conversion back from ``CARTESIAN`` takes dphi the other way round): the same BRDF value.
* ``CARTESIAN`` (v_x, v_y, v_z, l_x, l_y, l_z): the vectors themselves (normalised here).
"""
from __future__ import annotations

import numpy as np

from brdfcl.data.geometry import directions as directions_phi_h0

PARAMS = {"COS_TH": 1, "COS_TH_TD": 2, "RUSIN_TH_TD": 2, "RUSIN_TH_TD_PD": 3, "RUSIN_TH_PH_TD_PD": 4,
          "ISOTROPIC_TV_TL_DPHI": 3, "ISOTROPIC_TL_TV_PROJ_DPHI": 3, "SPHERICAL_TL_PL_TV_PV": 4, "CARTESIAN": 6}
"""The input parametrisations brdfcl reads, with their number of coordinates."""


def unit(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors (n, 3) at spherical angles (radians, theta from the normal z)."""
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


def half_difference(th: np.ndarray, ph: np.ndarray, td: np.ndarray,
                    pd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The direction pair of Rusinkiewicz angles: the pair of phi_h = 0
    (brdfcl.data.geometry.directions), both turned by ph about z."""
    wi, wo = directions_phi_h0(th, td, pd)
    c, s = np.cos(ph)[:, None], np.sin(ph)[:, None]

    def turn(v):
        return np.concatenate([v[:, :1] * c - v[:, 1:2] * s, v[:, :1] * s + v[:, 1:2] * c, v[:, 2:]], axis=1)
    return turn(wi), turn(wo)


def directions(param: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first direction, second direction), each (n, 3), of rows ``x`` (n, PARAMS[param]) in a
    parametrisation (the module's docstring gives each convention)."""
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    zero = np.zeros(n)
    if param == "COS_TH":
        h = unit(np.arccos(np.clip(x[:, 0], -1.0, 1.0)), zero)
        return h, h.copy()
    if param == "COS_TH_TD":
        th, td = (np.arccos(np.clip(c, -1.0, 1.0)) for c in x.T)
        return half_difference(th, zero, td, zero)
    if param == "RUSIN_TH_TD":
        return half_difference(x[:, 0], zero, x[:, 1], np.full(n, 0.5 * np.pi))
    if param == "RUSIN_TH_TD_PD":
        return half_difference(x[:, 0], zero, x[:, 1], x[:, 2])
    if param == "RUSIN_TH_PH_TD_PD":
        return half_difference(*x.T)
    if param == "ISOTROPIC_TV_TL_DPHI":
        return unit(x[:, 0], zero), unit(x[:, 1], x[:, 2])
    if param == "ISOTROPIC_TL_TV_PROJ_DPHI":
        theta_v = np.hypot(x[:, 1], x[:, 2])
        return unit(theta_v, np.arctan2(x[:, 2], x[:, 1])), unit(x[:, 0], zero)
    if param == "SPHERICAL_TL_PL_TV_PV":
        return unit(x[:, 2], x[:, 3]), unit(x[:, 0], x[:, 1])
    if param == "CARTESIAN":
        a, b = x[:, :3], x[:, 3:6]
        return a / np.linalg.norm(a, axis=1, keepdims=True), b / np.linalg.norm(b, axis=1, keepdims=True)
    raise ValueError(f"unknown ALTA parametrisation {param!r}; known: {', '.join(PARAMS)}")
