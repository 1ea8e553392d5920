"""Directional albedo of a fitted model, attached to each fit to flag energy gain.

``a(theta_i) = int f(wi, wo) cos theta_o dwo`` per channel, integrated over the half vector:
``wo = 2 (wi.h) h - wi``, ``dwo = 4 (wi.h) dwh``.  Every lobe of the model family (diffuse,
diffraction, Cook-Torrance) is centred on ``h = n`` whatever ``wi``, so a grid in ``(theta_h,
phi_h)`` graded towards ``theta_h = 0`` resolves lobes of any width: theta_h from 0 to the
horizon of ``wo`` (``tan 2 theta_h = -cos ti / (sin ti cos phi_h)``, so no cell straddles it)
in ``ALBEDO_PANELS`` log-spaced panels down to 1e-7 of that range, ``ALBEDO_GAUSS``
Gauss-Legendre points each; phi_h on [0, pi] (the integrand is even in phi_h) by the midpoint
rule with ``ALBEDO_PHI`` points.  Float64 reference values (``Model.reference``) on cells built
from ``h`` directly (sin theta_h exact down to 1e-7 rad).  Checked: a Lambertian lobe gives rho
to 1e-6; a GGX lobe with F = 1, alpha = 1e-3 gives 0.99999 at normal incidence.
"""
from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells

ALBEDO_THETA_DEG = (0.0, 30.0, 60.0, 75.0, 85.0)
ALBEDO_PANELS, ALBEDO_GAUSS, ALBEDO_PHI = 16, 5, 24
ALBEDO_LIMIT = 1.0 + 1e-3               # flag above: 1, plus the quadrature's error


def albedo_cells(theta_i: float) -> tuple[Cells, np.ndarray]:
    """Quadrature of the outgoing hemisphere for incidence theta_i (rad): (Cells, weights) with
    ``sum(weights * f * cos theta_o) = a(theta_i)`` (see module doc)."""
    si, ci = math.sin(theta_i), math.cos(theta_i)
    phi = (np.arange(ALBEDO_PHI) + 0.5) * math.pi / ALBEDO_PHI
    w_phi = 2.0 * math.pi / ALBEDO_PHI                           # [0, pi], doubled
    t_max = 0.5 * np.arctan2(ci, -si * np.cos(phi))               # wo on the horizon
    x, wx = np.polynomial.legendre.leggauss(ALBEDO_GAUSS)
    edges = np.concatenate([[0.0], np.geomspace(1e-7, 1.0, ALBEDO_PANELS)])
    a, b = edges[:-1, None], edges[1:, None]
    u = (0.5 * (b - a) * (x + 1) + a).ravel()                     # in (0, 1), graded towards 0
    wu = (0.5 * (b - a) * wx).ravel()
    th = t_max[:, None] * u[None, :]
    dth = t_max[:, None] * wu[None, :]
    P = np.broadcast_to(phi[:, None], th.shape)
    sh, ch = np.sin(th), np.cos(th)
    cd = si * sh * np.cos(P) + ci * ch                            # wi . h
    co = 2.0 * cd * ch - ci                                       # wo . n
    cells = Cells(sh.ravel(), ch.ravel(), cd.ravel(), np.full(th.size, ci), co.ravel())
    weight = (4.0 * cd * sh * dth * w_phi).ravel()                # dwo = 4 (wi.h) sin th dth dphi
    return cells, weight


@lru_cache(maxsize=4)
def _quadrature(theta_i_deg: tuple) -> tuple[Cells, np.ndarray, np.ndarray]:
    """Every angle's cells in one set: (Cells, weight x cos theta_o, the angle of each cell)."""
    parts = [albedo_cells(math.radians(t)) for t in theta_i_deg]
    cells = Cells(*(np.concatenate([getattr(c, k) for c, _ in parts]) for k in ("sh", "ch", "cd", "ci", "co")))
    wq = np.concatenate([w * np.maximum(c.co, 0.0) for c, w in parts])
    return cells, wq, np.repeat(np.arange(len(parts)), [len(c) for c, _ in parts])


_SETS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
CHUNK = 256                               # fits per predict launch (its output: CHUNK x C x cells)


def _on_engine(engine, theta_i_deg: tuple, values: np.ndarray) -> np.ndarray:
    """Model values (n, C, cells) of the quadrature on a compiled Engine, its cells uploaded once."""
    cells, _, _ = _quadrature(theta_i_deg)
    sets = _SETS.setdefault(engine, {})
    if theta_i_deg not in sets:
        n = len(cells)
        sets[theta_i_deg] = engine.upload_cells(["albedo"], [cells], [np.ones(n)],
                                                  [np.zeros((engine.model.n_channels, n))])
    cs = sets[theta_i_deg]
    return np.concatenate([engine.predict(cs, values[s:s + CHUNK], 0).astype(np.float64)
                           for s in range(0, len(values), CHUNK)])


def directional_albedo(model: Model, values: np.ndarray,
                       theta_i_deg: Sequence[float] = ALBEDO_THETA_DEG, engine=None) -> np.ndarray:
    """Directional albedo (n, angles, channels) of the model at each value vector (n, n_params):
    with ``engine`` (a compiled Engine of ``model``) every fit in one launch of its predict
    kernel, else the float64 reference, one evaluation per vector."""
    values = np.atleast_2d(np.asarray(values, dtype=np.float64))
    theta_i_deg = tuple(float(t) for t in theta_i_deg)
    cells, wq, angle = _quadrature(theta_i_deg)
    if engine is not None:
        p = _on_engine(engine, theta_i_deg, values)
    else:
        p = np.stack([model.reference(cells, v, jacobian=False) for v in values]) if len(values) else \
            np.zeros((0, model.n_channels, len(cells)))
    terms = np.where(np.isfinite(p), p, 0.0) * wq
    return np.stack([terms[:, :, angle == j].sum(axis=2) for j in range(len(theta_i_deg))], axis=1)
