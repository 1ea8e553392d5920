"""The report images of measured tables and their fits: lit spheres (PNG and EXR), a thumbnail,
the measured turntable of the page's live view and the slice figures (SVG), from one Plan of
every view (brdfcl.report.view.views) and the fits evaluated for many materials at once
(brdfcl.report.view.evaluate).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdfcl.report.files import atomic_write_text
from brdfcl.report.view.evaluate import Evaluator, Fitted
from brdfcl.report.view.slices import write_slice_figures
from brdfcl.report.view.sphere import (
    DEFAULT_LIGHTS,
    ENV_SIZE,
    as_model,
    exposed,
    panels,
    write_png,
    write_sphere_images,
)
from brdfcl.report.view.views import plan as view_plan


def curves(plan, measured, fitted: Fitted) -> dict:
    """The slice figures' curves (brdfcl.report.view.slices.slice_curves' form) from values at
    the plan's points."""
    out = {}
    offset = plan.in_plane.start
    for v in plan.slices:
        cv = {"theta_o": v.theta_o, "measured": measured[:, v.span] * v.cos, "fitted": fitted.points[:, v.span] * v.cos}
        if v.dphi is None:
            local = slice(v.span.start - offset, v.span.stop - offset)
            cv.update({k: lobe[:, local] * v.cos for k, lobe in fitted.lobes.items()})
        out[v.dphi, v.theta_i] = cv
    return out


@dataclass
class Measured:
    """A table's side of its images, which needs no fit: its values at the plan's points (3, n),
    its sphere images ({label: radiance}), how their panels show them (sphere.exposed) and the
    turntable files written."""

    at_points: np.ndarray
    images: dict
    files: list
    shown: dict


def measure(out_dir, name, values, plan) -> Measured:
    """The measured side of a material's images from its table at the plan's cells (``values``,
    ``Plan.table_values``), the turntable written (its exposure the first sphere's, as the page's)."""
    at_points, at_env = plan.measured(values)
    images = plan.images(at_points, at_env)
    shown = exposed(images)
    files = write_turntable(out_dir, name, plan, values, shown[plan.spheres[0].label][0]) if plan.turntable else []
    return Measured(at_points, images, files, shown)


def write_material(out_dir, name, values, model, fitted: Fitted, plan, measured: Measured | None = None):
    """Spheres, thumbnail and slices of one material (``values``: its table at the plan's cells,
    ``Plan.table_values``; or its `measure`, ``measured``, made before) with its ``fitted``
    values; returns (paths, {image name: caption})."""
    if measured is None:
        measured = measure(out_dir, name, values, plan)
    fit = plan.images(fitted.points, fitted.env)
    lights = [(v.label, v.kind, v.light) for v in plan.spheres]
    paths, captions = write_sphere_images(out_dir, name, model.spec, lights, measured.images, fit, measured.shown)
    paths += measured.files + write_slice_figures(out_dir, name, model, curves(plan, measured.at_points, fitted))
    return paths, captions


def write_turntable(out_dir, name, plan, values, scale):
    """The measured table's spheres under a point light at each of the plan's turntable angles
    from the view (azimuth 0), side by side in ``NAME-turntable.png`` (sRGB at ``scale``, the
    first light's exposure; black off the sphere, as the live view), and what they are in
    ``NAME-turntable.json`` (angles, their step, white in 1/sr): the page's live view shows the
    one nearest its light, turned to its azimuth (brdfcl.report.view.webgl)."""
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    png = Path(out_dir) / f"{name}-turntable.png"
    write_png(png, panels(plan.turntable_images(values), scale, gap=0, background=0.0))
    angles = [float(v.label) for v in plan.turntable]
    step = angles[1] - angles[0] if len(angles) > 1 else 0.0
    info = {"angles": [round(a, 3) for a in angles], "step": round(step, 3), "white": 1.0 / scale}
    atomic_write_text(png.with_suffix(".json"), json.dumps(info))
    return [png, png.with_suffix(".json")]


def write_images(out_dir, name, table, model, values, lights=DEFAULT_LIGHTS, size=160, env_size=ENV_SIZE,
                 engine=None):
    """`write_material` for one fit: ``table`` a MerlTable or (3, N_CELLS) array, ``values`` a
    vector or {name: value}; the model is evaluated with ``engine`` or its float64 reference."""
    model, values = as_model(model, values)
    plan = view_plan(lights, size, env_size)
    fitted = Evaluator(plan, model, engine)([values])[0]
    return write_material(Path(out_dir), name, plan.table_values(table), model, fitted, plan)
