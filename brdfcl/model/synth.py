"""Synthetic MERL databases from known parameters: the embedded demo database.

Each demo material is a model string and its true parameters; ``write_synth``
tabulates it at the bin centres (float64 reference), optionally with
multiplicative noise and missing cells, and writes ``NAME.binary`` plus
``truth.json`` (model and parameters of every material) so that fits can be
checked against the truth.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from brdfcl.data.geometry import table_geometry
from brdfcl.data.merl import N_CELLS, write_merl
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells

DEMO = {
    # Expected verdicts of `brdfcl analyze` on these: diffraction for the smooth metal only.
    # smooth metal: sharp specular peak with a strong, wide diffraction halo around it
    "synth-smooth-metal": ("diffuse+diffraction:hp+ggx:smith:schlick", {
        "diffuse.rho": (0.004, 0.003, 0.002), "diffraction.rho": (0.03, 0.025, 0.018),
        "diffraction.a": 0.8, "ct.rho": (0.9, 0.8, 0.6), "ct.alpha": 0.02, "ct.F0": (0.9, 0.8, 0.5)}),
    # rough metal: a broad Beckmann lobe and no diffraction (Cook-Torrance explains it all)
    "synth-rough-metal": ("diffuse+beckmann:smith:schlick", {
        "diffuse.rho": (0.01, 0.01, 0.012), "ct.rho": (0.7, 0.65, 0.6), "ct.alpha": 0.3,
        "ct.F0": (0.8, 0.75, 0.7)}),
    # smooth plastic: coloured diffuse base, white dielectric coat, no diffraction at all
    "synth-smooth-plastic": ("diffuse+ggx:smith:dielectric", {
        "diffuse.rho": (0.5, 0.06, 0.04), "ct.rho": (1.0, 1.0, 1.0), "ct.alpha": 0.03, "ct.eta": 1.5}),
    # fabric-like: mostly diffuse with a faint, very broad sheen
    "synth-fabric": ("diffuse+beckmann:vcavity:none", {
        "diffuse.rho": (0.3, 0.25, 0.4), "ct.rho": (0.05, 0.05, 0.06), "ct.alpha": 0.6}),
    # mirror-like: alpha ~ 1e-3, the stiff case
    "synth-mirror": ("diffuse+ggx:smith:schlick", {
        "diffuse.rho": (0.01, 0.01, 0.01), "ct.rho": (0.95, 0.95, 0.95), "ct.alpha": 1e-3,
        "ct.F0": (0.9, 0.9, 0.9)}),
}


def demo_values(model: Model, params: dict) -> np.ndarray:
    """Value vector of a model from {name: scalar or (r, g, b)}."""
    v = model.defaults()
    for k, val in params.items():
        if np.ndim(val):
            for ch, x in zip("rgb", val):
                v[model.names.index(f"{k}_{ch}")] = x
        else:
            v[model.names.index(k)] = val
    return v


def tabulate(model: Model, values, geom=None) -> np.ndarray:
    """BRDF table (3, N_CELLS) of a model at the bin centres, NaN below the horizon."""
    geom = geom or table_geometry()
    mask = geom.above_horizon
    out = np.full((3, N_CELLS), np.nan)
    idx = np.flatnonzero(mask)
    for s in range(0, idx.size, 262144):
        part = idx[s:s + 262144]
        out[:, part] = model.reference(Cells.from_geometry(geom, part), values, jacobian=False)
    return out


def write_synth(out_dir, materials=None, noise=0.0, missing=0.0, seed=0, log=print):
    """Write the demo materials (or a subset) to out_dir; returns the truth dict."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = list(DEMO) if materials is None else list(materials)
    unknown = [n for n in names if n not in DEMO]
    if unknown:
        raise ValueError(f"unknown demo material(s) {', '.join(unknown)}; valid: {', '.join(DEMO)}")
    rng = np.random.default_rng(seed)
    truth = {}
    for name in names:
        spec, params = DEMO[name]
        model = Model(spec)
        values = demo_values(model, params)
        table = tabulate(model, values)
        if noise > 0:
            table *= 1.0 + noise * rng.standard_normal(table.shape)
            table = np.maximum(table, 0.0)
        if missing > 0:
            drop = rng.random(N_CELLS) < missing
            table[:, drop] = np.nan
        write_merl(out_dir / f"{name}.binary", table)
        truth[name] = {"model": model.spec, "params": model.as_dict(values)}
        if log:
            log(f"{name}: {model.spec}")
    tmp = out_dir / "truth.json.tmp"
    tmp.write_text(json.dumps({"noise": noise, "missing": missing, "seed": seed, "definition": _fingerprint(),
                               "materials": truth}, indent=1))
    os.replace(tmp, out_dir / "truth.json")
    return truth


def _fingerprint():
    return hashlib.sha1(repr(sorted(DEMO.items())).encode()).hexdigest()[:16]


def demo_dir() -> Path:
    """The demo database, generated into the user's cache (35 MB per material) on first use and
    again whenever the demo definition changes."""
    base = Path(os.environ.get("BRDFCL_CACHE", Path.home() / ".cache" / "brdfcl")) / "demo"
    try:
        current = json.loads((base / "truth.json").read_text()).get("definition") == _fingerprint()
    except (OSError, ValueError):
        current = False
    if not current or any(not (base / f"{n}.binary").exists() for n in DEMO):
        write_synth(base, log=None)
    return base
