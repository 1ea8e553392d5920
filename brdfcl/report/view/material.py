"""The report images of measured tables and their fits: lit spheres (PNG and EXR), a thumbnail
and the slice figures (SVG), from one Plan of every view (brdfcl.report.view.views) and the fits
evaluated for many materials at once (brdfcl.report.view.evaluate).
"""
from __future__ import annotations

from pathlib import Path

from brdfcl.report.view.evaluate import Evaluator, Fitted
from brdfcl.report.view.slices import write_slice_figures
from brdfcl.report.view.sphere import DEFAULT_LIGHTS, ENV_SIZE, as_model, write_sphere_images
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


def write_material(out_dir, name, values, model, fitted: Fitted, plan):
    """Spheres, thumbnail and slices of one material (``values``: its table at the plan's cells,
    ``Plan.table_values``) with its ``fitted`` values; returns (paths, {image name: caption})."""
    at_points, at_env = plan.measured(values)
    measured = plan.images(at_points, at_env)
    fit = plan.images(fitted.points, fitted.env)
    lights = [(v.label, v.kind, v.light) for v in plan.spheres]
    paths, captions = write_sphere_images(out_dir, name, model.spec, lights, measured, fit)
    return paths + write_slice_figures(out_dir, name, model, curves(plan, at_points, fitted)), captions


def write_images(out_dir, name, table, model, values, lights=DEFAULT_LIGHTS, size=160, env_size=ENV_SIZE,
                 engine=None):
    """`write_material` for one fit: ``table`` a MerlTable or (3, N_CELLS) array, ``values`` a
    vector or {name: value}; the model is evaluated with ``engine`` or its float64 reference."""
    model, values = as_model(model, values)
    plan = view_plan(lights, size, env_size)
    fitted = Evaluator(plan, model, engine)([values])[0]
    return write_material(Path(out_dir), name, plan.table_values(table), model, fitted, plan)
