"""Which images a report shows of each material, and drawing those that are out of date.

A material's images live in ``OUT/report/NAME/`` with a ``.stamp`` naming the fit and table
they show (and the sphere images' captions); a report draws again only the materials whose
stamp differs.  Tables: the lit spheres, thumbnail, measured turntable and slices (brdfcl.report.view.material),
the fits of one model evaluated together on the engine and the drawing spread over a process
per core (brdfcl.report.view.drawer); scattered samples: the in-plane figure
(brdfcl.report.sample_figures).

A fit job may start those processes when it starts (`Beside`): at a low priority, they read each
table and draw what needs no fit (its measured spheres and turntable) in the CPU time the fits
leave, and keep it; each material's fitted side then goes to the process holding its measured
side.
"""
from __future__ import annotations

import json
import logging
import os
from concurrent.futures import as_completed
from pathlib import Path

from brdfcl.device.errors import DeviceError, ProgramError
from brdfcl.model.compose import Model
from brdfcl.report.view.drawer import Drawers, InProcess
from brdfcl.report.view.evaluate import CHUNK, Evaluator
from brdfcl.report.view.material import measure, write_material
from brdfcl.report.view.sphere import DEFAULT_LIGHTS
from brdfcl.report.view.views import plan as view_plan

_log = logging.getLogger("brdfcl")
# key, grazing and environment light
REPORT_LIGHTS = tuple(light for light in DEFAULT_LIGHTS if light[0] in ("key", "grazing", "env"))
TURNTABLE_DEG = tuple(range(0, 180, 15))    # the live view's measured spheres: light angles from the view
# brdfcl.report.view.views.plan: lights, sphere size, environment size, turntable angles and size
PLAN = (REPORT_LIGHTS, 128, 64, TURNTABLE_DEG, 64)
PER_WORKER = 12                   # materials a worker process must have to be worth starting
DRAW_PROCESSES = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
BESIDE_NICE = 10                  # the workers beside the fits: their niceness increment (and SCHED_IDLE)
BESIDE_KEPT = 100                 # measured sides a worker keeps at most (~2 MB each)
_MEASURED: dict = {}              # in a worker: (table, mtime) -> its measured side, made beside the fits


class Beside:
    """Image workers started with a fit job (``tables``: material name -> measured table file)
    that draw, beside the fits, the measured side of each table whose images are not up to date
    (brdfcl.report.view.material.measure), keeping it for `draw_images`; no workers where the
    job would not start them (`_pool`)."""

    def __init__(self, rep, tables: dict, read_cells):
        todo = [(n, p) for n, p in tables.items() if os.path.exists(p) and not _measured_current(rep / n, p)]
        self.pool = Drawers(DRAW_PROCESSES, nice=BESIDE_NICE, idle=True) \
            if len(todo) >= PER_WORKER * DRAW_PROCESSES and DRAW_PROCESSES > 1 else None
        self.worker: dict[str, int] = {}
        if self.pool is None:
            return
        for i, (name, path) in enumerate(todo[:BESIDE_KEPT * self.pool.size]):
            self.worker[name] = i % self.pool.size
            self.pool.submit(_measure, rep, name, path, read_cells, worker=i % self.pool.size)

    def close(self) -> None:
        """End the workers (where `draw_images` did not take them)."""
        if self.pool is not None:
            self.pool.__exit__(None, None, None)
            self.pool = None


def _key(e):
    return f"{e.model}|{sorted(e.params.items())}|{os.path.getmtime(e.table)}"


def draw_images(rep, entries, read_cells, engine=None, beside: Beside | None = None, on_images=None) -> dict:
    """{name: images} of every entry with a measurement: kept in ``rep/NAME/`` when newer than
    its table and fit, else drawn, the fits of one model evaluated together (CHUNK at a time);
    ``read_cells(path, index)``: a table's BRDF (3, len(index)) at the views' cells (the MERL
    table's, brdfcl.data.geometry.table_values); ``beside``: the job's workers, holding measured
    sides (they are ended here); ``on_images(name, images)``: called with each material's images
    as they are ready (the drawn ones while the others are drawn)."""
    out: dict = {}

    def ready(name, images):
        out[name] = images
        if on_images is not None:
            on_images(name, images)
    todo: dict[str, list] = {}
    for e in entries:
        if e.table is None or not os.path.exists(e.table):
            continue
        stamp = _stamp(rep / e.name)
        if stamp.get("key") == _key(e):
            ready(e.name, _existing(rep / e.name, e.name, stamp))
        elif not e.tabulated:
            ready(e.name, _sample_images(rep / e.name, e))
        else:
            todo.setdefault(e.model, []).append(e)
    pool = beside.pool if beside is not None and beside.pool is not None else None
    placed = beside.worker if pool is not None and beside is not None else {}
    if beside is not None:
        beside.pool = None                            # ended here
    if pool is not None:
        pool.wake()                                   # the fits are done: the drawing is all there is
    if not todo:
        if pool is not None:
            pool.__exit__(None, None, None)
        return out
    plan = view_plan(*PLAN)
    with pool or _pool(sum(len(g) for g in todo.values())) as pool:
        drawn = []
        for spec, group in todo.items():
            model = Model(spec)
            evaluate = Evaluator(plan, model, _engine(engine, model))
            for first in range(0, len(group), CHUNK):
                part = group[first:first + CHUNK]
                fitted = evaluate([[e.params[n] for n in model.names] for e in part])
                drawn += [pool.submit(_draw, rep, e.name, e.table, _key(e), spec, f, read_cells,
                                      worker=placed.get(e.name)) for e, f in zip(part, fitted)]
        for f in as_completed(drawn):
            ready(*f.result())
    return out



def _pool(n):
    """Where the images are drawn: a process per CPU for a report of many materials (drawing
    holds the GIL; a worker costs about a second to start, some ten materials' drawing), this
    process for fewer."""
    return Drawers(DRAW_PROCESSES) if n >= PER_WORKER * DRAW_PROCESSES and DRAW_PROCESSES > 1 else InProcess()


def _measure(rep, name, table, read_cells):
    """In a worker beside the fits: the measured side of a table's images, kept for `_draw`; a
    table that cannot be read is left to `_draw`, which says why."""
    plan = view_plan(*PLAN)
    try:
        _MEASURED[table, os.path.getmtime(table)] = measure(rep / name, name, read_cells(table, plan.table_cells), plan)
    except Exception:
        pass
    return name


def _measured_current(d, table) -> bool:
    """Whether the images in ``d`` were drawn from the table as it is now (their stamp's key ends
    with its modification time, `_key`)."""
    return _stamp(d).get("key", "").rpartition("|")[2] == str(os.path.getmtime(table))


def _draw(rep, name, table, key, spec, fitted, read_cells):
    """One material's images (brdfcl.report.view.material) and their stamp: (name, images); the
    measured side made beside the fits where it was."""
    model, plan = Model(spec), view_plan(*PLAN)
    measured = _MEASURED.pop((table, os.path.getmtime(table)), None)
    values = None if measured is not None else read_cells(table, plan.table_cells)
    paths, captions = write_material(rep / name, name, values, model, fitted, plan, measured)
    _write_stamp(rep / name, key, captions)
    return name, _classify(paths, name, captions)


def _engine(engine, model):
    """A compiled Engine of ``model``: the run's (``engine(spec)``), else the default device's;
    None where no device builds it (a one-line warning)."""
    try:
        if engine is not None:
            return engine(model.spec)
        from brdfcl.device.engine import Engine
        return Engine(model)
    except (DeviceError, ProgramError) as e:
        _log.warning(f"brdfcl: report images of {model.spec} with the float64 reference: {e}")
        return None


def _sample_images(d, e) -> dict:
    """Scattered samples: measured against fitted in the plane of incidence (no spheres or
    slices: those need a table)."""
    from brdfcl.data.readers import read_samples
    from brdfcl.report.sample_figures import figure_in_plane
    samples, model = read_samples(e.table), e.fitted_model()
    if samples.n_channels != model.n_channels:      # a spectral file fitted as RGB (fit-all --rgb)
        try:
            from brdfcl.data.rgb import to_rgb
            samples = to_rgb(samples)
        except (ImportError, ValueError):
            return {}
    if samples.n_channels != model.n_channels:
        return {}
    d.mkdir(parents=True, exist_ok=True)
    path = d / f"{e.name}-in-plane-slices.png"
    figure_in_plane(samples, model, e.params, path)
    _write_stamp(d, _key(e), {})
    return _classify([path], e.name)


def _stamp(d) -> dict:
    """What ``d/.stamp`` says the images there show: {"key": fit and table, "captions"}."""
    try:
        stamp = json.loads((d / ".stamp").read_text())
    except (OSError, ValueError):
        return {}
    return stamp if isinstance(stamp, dict) else {}


def _write_stamp(d, key, captions):
    (d / ".stamp").write_text(json.dumps({"key": key, "captions": captions}))


def _existing(d, name, stamp):
    return _classify(sorted(d.iterdir()), name, stamp.get("captions") or {})


def _classify(paths, name, captions=None):
    images = [Path(p) for p in paths if str(p).endswith((".png", ".svg"))]
    return {"thumb": [p for p in images if p.name == f"{name}-thumb.png"],
            "spheres": [p for p in images if "-sphere-" in p.name],
            "slices": [p for p in images if p.name.endswith(("-slices.svg", "-lobes.svg", "-slices.png"))],
            "turntable": [p for p in images if p.name == f"{name}-turntable.png"],
            "exr": [Path(p) for p in paths if str(p).endswith(".exr")],
            "captions": captions or {}}
