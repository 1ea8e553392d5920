"""Synthetic materials from known parameters: the embedded demo database, and spectral materials
scattered like a real measurement.

Each demo material is a model string and its true parameters; ``write_synth``
tabulates it at the bin centres (float64 reference), optionally with
multiplicative noise and missing cells, and writes ``NAME.binary`` plus
``truth.json`` (model and parameters of every material) so that fits can be
checked against the truth.

``SPECTRAL`` holds spectral materials in the same way, their per-band parameters given by a rule
of the wavelength (a constant, ``Ramp``, ``Bump``); ``write_spectral_synth`` evaluates them at the
sample directions and bands of a real measurement file (``brdfcl synth --like FILE``) and writes
them as scattered samples (Cornell ``.brdf`` and/or CSV) with ``truth.json``.
"""
from __future__ import annotations

import hashlib
import json
import os
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdfcl._cache import cache_dir
from brdfcl._words import count, noun
from brdfcl.data.cornell import write_cornell
from brdfcl.data.csvsamples import write_csv
from brdfcl.data.errors import DataError
from brdfcl.data.geometry import table_geometry
from brdfcl.data.inputs import check_output_not_input
from brdfcl.data.merl import N_CELLS, write_merl
from brdfcl.data.readers import read_samples
from brdfcl.data.samples import RGB_WAVELENGTHS_UM, Samples, make_samples
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
        raise ValueError(f"unknown demo {noun(len(unknown), 'material')} {', '.join(unknown)}; valid: "
                         f"{', '.join(DEMO)}")
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


def truth_of(path) -> dict | None:
    """The known truth of a synthetic measurement: its entry ({"model", "params"}) in the
    ``truth.json`` beside the file (``brdfcl synth`` and the demo write one), looked up by the
    file's name without its suffix, beside the path as given and, for a link, beside its target;
    None where there is none (a real measurement) or it cannot be read."""
    path = Path(path)
    for folder in dict.fromkeys((path.parent, path.resolve().parent)):
        try:
            doc = json.loads((folder / "truth.json").read_text())
        except (OSError, ValueError):
            continue
        entry = doc.get("materials", {}).get(path.stem) if isinstance(doc, dict) else None
        if isinstance(entry, dict) and isinstance(entry.get("params"), dict) and "model" in entry:
            return {"model": str(entry["model"]), "params": dict(entry["params"]),
                    "noise": doc.get("noise"), "file": str(folder / "truth.json")}
    return None


def _fingerprint():
    return hashlib.sha1(repr(sorted(DEMO.items())).encode()).hexdigest()[:16]


def demo_dir() -> Path:
    """The demo database, generated into brdfcl's cache (``demo/`` in brdfcl._cache.cache_dir,
    35 MB per material) on first use and again whenever the demo definition changes."""
    base = cache_dir() / "demo"
    try:
        current = json.loads((base / "truth.json").read_text()).get("definition") == _fingerprint()
    except (OSError, ValueError):
        current = False
    if not current or any(not (base / f"{n}.binary").exists() for n in DEMO):
        write_synth(base, log=None)
    return base


# --- spectral materials at the directions of a real measurement ----------------------------------

@dataclass(frozen=True)
class Ramp:
    """A parameter linear in the wavelength: ``at_400nm`` at 0.4 um, ``at_700nm`` at 0.7 um
    (extrapolated beyond, then kept within the parameter's bounds)."""

    at_400nm: float
    at_700nm: float

    def __call__(self, lam_um: float) -> float:
        return self.at_400nm + (self.at_700nm - self.at_400nm) * (lam_um - 0.4) / 0.3


@dataclass(frozen=True)
class Bump:
    """A coloured spectrum: ``base + height * exp(-((lambda - centre_um) / width_um)^2)``."""

    base: float
    height: float
    centre_um: float
    width_um: float

    def __call__(self, lam_um: float) -> float:
        return self.base + self.height * float(np.exp(-(((lam_um - self.centre_um) / self.width_um) ** 2)))


SPECTRAL: dict[str, tuple[str, dict[str, float | Callable[[float], float]]]] = {
    # With diffraction: a wide diffraction halo whose amplitude rho_c (um^4) is the same in every band, so that its
    # peak follows lambda^-4 exactly, around a sharp GGX peak of a white dielectric-like coat;
    # a nearly grey diffuse base.
    "synth-spectral-diffraction": ("diffuse+diffraction:hp+ggx", {
        "diffuse.rho": Ramp(0.04, 0.03), "diffraction.rho": 0.01, "diffraction.a": 2.0,
        "ct.rho": 1.0, "ct.alpha": 0.05, "ct.F0": 0.04}),
    # Without diffraction: blue paint under a clear coat (krylon-like): a coloured diffuse
    # spectrum peaking at 460 nm and a white GGX lobe.
    "synth-spectral-plastic": ("diffuse+ggx", {
        "diffuse.rho": Bump(0.04, 0.3, 0.46, 0.05), "ct.rho": 1.0, "ct.alpha": 0.08, "ct.F0": 0.04}),
}
"""Spectral synthetic materials: name -> (model, {parameter: value}).  A parameter with one value
per band (``diffuse.rho``, ``diffraction.rho``, ``ct.rho``, ``ct.F0``) is given by a constant or a
rule of the wavelength in um (``Ramp``, ``Bump``), evaluated at each band of the file given."""

SPECTRAL_FORMATS = {"brdf": ".brdf", "csv": ".csv"}
"""The formats ``write_spectral_synth`` writes: name -> file suffix."""


def spectral_values(model: Model, params: dict) -> np.ndarray:
    """Value vector of a spectral model from {name: value or rule of the wavelength (um)}; a
    per-band value is kept within the parameter's bounds."""
    v = model.defaults()
    for k, val in params.items():
        if k in model.names:
            if callable(val):
                raise ValueError(f"{k} is one value for every band, not a rule of the wavelength")
            v[model.names.index(k)] = float(val)
            continue
        cols = [model.names.index(f"{k}_{ch}") for ch in model.channels if f"{k}_{ch}" in model.names]
        if len(cols) != model.n_channels:
            raise ValueError(f"{k} is not a parameter of {model.spec}; parameters: {', '.join(model.names)}")
        for col, lam in zip(cols, model.lambdas):
            x = float(val(float(lam))) if callable(val) else float(val)
            v[col] = min(max(x, model.lo[col]), model.hi[col])
    return v


def spectral_samples(name: str, like: Samples, noise: float = 0.0, seed: int = 0) -> tuple[Samples, Model, np.ndarray]:
    """(samples, model, true values) of spectral material ``name`` at the directions and bands of
    ``like``: the float64 reference, times exp(noise * N(0, 1)) per value if ``noise`` (the
    draws seeded by ``seed`` and the name, so a material's noise does not depend on the others)."""
    spec, params = SPECTRAL[name]
    model = Model(spec, lambdas=tuple(float(x) for x in like.wavelengths))
    values = spectral_values(model, params)
    v = model.reference(Cells.from_directions(like.wi, like.wo), values, jacobian=False).T
    if noise > 0:
        rng = np.random.default_rng([seed, zlib.crc32(name.encode())])
        v = v * np.exp(noise * rng.standard_normal(v.shape))
    if not np.isfinite(v).all():
        raise ValueError(f"{name}: the model is not finite at some directions of {like.path or like.name}")
    out = make_samples(None, like.theta_i, like.phi_i, like.theta_o, like.phi_o, v, like.channels,
                       name=name, weights=like.weights)
    return out, model, values


def _formats(formats: str | Iterable[str]) -> list[str]:
    names = [f.strip().lower().lstrip(".") for f in ([formats] if isinstance(formats, str) else formats)]
    names = list(dict.fromkeys(f for f in names if f))
    bad = [f for f in names if f not in SPECTRAL_FORMATS]
    if bad or not names:
        raise ValueError(f"unknown {noun(len(bad), 'format')} {', '.join(bad) or '(none given)'}; valid: "
                         f"{', '.join(SPECTRAL_FORMATS)}")
    return names


def write_spectral_synth(out_dir, like, materials=None, noise=0.0, seed=0, formats=("brdf", "csv"), log=print):
    """Write the spectral materials (or a subset) at the sample directions and bands of the
    measurement file ``like`` (any file brdfcl.data.readers reads) to ``out_dir``: ``NAME.brdf``
    and/or ``NAME.csv`` (radians, exact round trip) per material, each format in a folder of its
    own (``out_dir/brdf/``, ``out_dir/csv/``) when there are two, so that a folder never holds one
    material twice, and ``truth.json`` (model, bands, parameters, noise, seed and the file), each
    written atomically; returns the truth dict.

    DataError (one line, naming the file) if ``like`` cannot be read or has no spectral bands;
    InputOverwriteError if ``out_dir`` is, or holds, the folder of ``like``; ValueError for an
    unknown material or format."""
    names = list(SPECTRAL) if materials is None else list(materials)
    unknown = [n for n in names if n not in SPECTRAL]
    if unknown:
        raise ValueError(f"unknown spectral {noun(len(unknown), 'material')} {', '.join(unknown)}; valid: "
                         f"{', '.join(SPECTRAL)}")
    fmts = _formats(formats)
    if noise < 0 or not np.isfinite(noise):
        raise ValueError(f"noise {noise}: must be a finite number >= 0")
    src = read_samples(like)
    rgb = [c.name for c in src.channels if c.name.upper() in RGB_WAVELENGTHS_UM]
    if rgb:
        raise DataError(like, f"channels {', '.join(rgb)} are not spectral bands: synthetic spectral "
                              "materials need a measurement with one channel per wavelength")
    check_output_not_input(like, out_dir)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    truth = {}
    for name in names:
        samples, model, values = spectral_samples(name, src, noise=noise, seed=seed)
        for f in fmts:
            folder = out_dir if len(fmts) == 1 else out_dir / f      # one material, one name per folder
            folder.mkdir(exist_ok=True)
            path = folder / f"{name}{SPECTRAL_FORMATS[f]}"
            tmp = folder / f".{path.name}.tmp"          # hidden: never read as a measurement
            if f == "brdf":
                write_cornell(samples, tmp)
            else:
                write_csv(samples, tmp, radians=True)
            os.replace(tmp, path)
        truth[name] = {"model": model.spec, "params": model.as_dict(values),
                       "rules": {k: repr(v) for k, v in SPECTRAL[name][1].items()}}
        if log:
            where = [name + SPECTRAL_FORMATS[f] if len(fmts) == 1 else f"{f}/{name}{SPECTRAL_FORMATS[f]}"
                     for f in fmts]
            log(f"{name}: {model.spec} at {count(samples.n_samples, 'sample')} x {count(samples.n_channels, 'band')} "
                f"({', '.join(where)})")
    doc = {"like": os.path.abspath(os.fspath(like)), "formats": fmts, "noise": noise, "seed": seed,
           "wavelengths_nm": [1000.0 * float(x) for x in src.wavelengths],
           "n_samples": src.n_samples, "materials": truth}
    tmp = out_dir / "truth.json.tmp"
    tmp.write_text(json.dumps(doc, indent=1))
    os.replace(tmp, out_dir / "truth.json")
    return truth
