"""Lit spheres and slice plots (brdfcl.report.view) on the synthetic demo materials, whose tables are
the model's own values at the bin centres: the table sphere and the model sphere of one material
differ only by the table's sampling and the trilinear lookup."""
import json

import numpy as np
import pytest

from brdfcl.data.geometry import table_geometry
from brdfcl.data.merl import read_merl
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.report.view import sphere
from brdfcl.report.view.evaluate import Evaluator
from brdfcl.report.view.lookup import _interpolate, corners, interpolate, rusinkiewicz, table_lookup
from brdfcl.report.view.material import curves, write_images
from brdfcl.report.view.slices import slice_curves, slice_directions, slice_values, write_slices
from brdfcl.report.view.sphere import DEFAULT_LIGHTS, render_model_sphere, render_table_sphere, sphere_normals
from brdfcl.report.view.svgplot import TOLERANCE_PX, Figure, _thin, _thin_runs
from brdfcl.report.view.views import plan

NAME = "synth-smooth-metal"


@pytest.fixture(scope="module")
def metal(demo_db):
    truth = json.loads((demo_db / "truth.json").read_text())["materials"][NAME]
    return read_merl(demo_db / f"{NAME}.binary"), Model(truth["model"]), truth["params"]


def test_lookup_inverts_the_table_geometry(metal):
    table, _, _ = metal
    g = table_geometry()
    idx = np.flatnonzero(g.above_horizon)[::101]
    th, td, pd = rusinkiewicz(g.wi[idx], g.wo[idx])
    for a, b in ((th, g.theta_h), (td, g.theta_d), (pd, g.phi_d)):
        np.testing.assert_allclose(a, b[idx], atol=1e-9)
    brdf = table.brdf()
    for interp in ("nearest", "linear", "log"):
        np.testing.assert_allclose(table_lookup(brdf, g.wi[idx], g.wo[idx], interp), brdf[:, idx], rtol=1e-8)


def test_missing_cells(metal):
    table, _, _ = metal
    g = table_geometry()
    idx = np.flatnonzero(g.above_horizon)[1000:1010]
    brdf = table.brdf().copy()
    brdf[:, idx[0]] = np.nan
    wi, wo = g.wi[idx], g.wo[idx]
    near = table_lookup(brdf, wi, wo, "nearest")
    assert np.isnan(near[:, 0]).all() and np.isfinite(near[:, 1:]).all()
    for interp in ("linear", "log"):                       # an isolated hole is filled by neighbours
        filled = table_lookup(brdf, wi, wo, interp)
        assert np.isfinite(filled).all()
        np.testing.assert_allclose(filled[:, 0], table.brdf()[:, idx[0]], rtol=0.05)
    brdf[:] = np.nan
    assert np.isnan(table_lookup(brdf, wi, wo)).all()


@pytest.mark.parametrize("name", ["synth-smooth-metal", "synth-rough-metal", "synth-smooth-plastic",
                                  "synth-fabric", "synth-mirror"])
def test_model_sphere_matches_table_sphere(demo_db, name):
    """Median relative difference, measured: <= 0.13 % under the point lights (0.31 % for the
    plastic's grazing light; single pixels up to 60 % on the sharpest highlights, which the
    table's bins cannot follow) and <= 0.15 % in the environment, except the mirror (alpha =
    1e-3): 4.4 %, its peak narrower than the table's first theta_h bins."""
    truth = json.loads((demo_db / "truth.json").read_text())["materials"][name]
    table, model = read_merl(demo_db / f"{name}.binary"), Model(truth["model"])
    for label, kind, d in DEFAULT_LIGHTS:
        size = 32 if kind == "env" else 96
        fit = render_model_sphere(model, truth["params"], d, size, kind)
        meas = render_table_sphere(table, d, size, kind)
        ok = fit > 0
        assert ok.sum() > 100 and np.isfinite(meas[ok]).all(), label
        rel = np.median(np.abs(meas[ok] - fit[ok]) / fit[ok])
        bound = 0.06 if kind == "env" and name == "synth-mirror" else 0.005
        assert rel < bound, (label, rel)


def test_centre_pixel_is_the_brdf_at_normal_incidence(metal):
    table, model, params = metal
    img = render_model_sphere(model, params, (0.0, 0.0, 1.0), size=33)
    z = np.array([[0.0, 0.0, 1.0]])
    values = np.array([params[n] for n in model.names])
    expected = model.reference(Cells.from_directions(z, z), values, jacobian=False)[:, 0]
    np.testing.assert_allclose(img[16, 16], expected, rtol=1e-12)
    meas = render_table_sphere(table, (0.0, 0.0, 1.0), size=33)
    np.testing.assert_allclose(meas[16, 16], table_lookup(table, z, z)[:, 0], rtol=1e-12)


def test_orientation_and_nan_outside_the_disc(metal):
    table, model, params = metal
    normals, inside = sphere_normals(40)
    assert normals[0, 20, 1] > 0.9 and normals[20, -1, 0] > 0.9          # row 0 is up, x right
    for kind in ("point", "env"):
        for img in (render_model_sphere(model, params, (0.0, 0.6, 0.8), 40, kind),
                    render_table_sphere(table, (0.0, 0.6, 0.8), 40, kind)):
            assert img.shape == (40, 40, 3)
            assert (np.isnan(img).any(-1) == ~inside).all()
            assert (img[inside] >= 0).all()
    img = render_model_sphere(model, params, (0.0, 0.6, 0.8), 40)
    assert img[:20][inside[:20]].mean() > 10 * img[20:][inside[20:]].mean()  # light from above


def test_environment_white_furnace(monkeypatch):
    """A Lambertian sphere in a uniform environment of radiance 1 shows its albedo everywhere."""
    for k in ("SKY_ZENITH", "SKY_HORIZON", "GROUND"):
        monkeypatch.setattr(sphere, k, np.ones(3))
    img = render_model_sphere("diffuse", [0.5, 0.3, 0.1], (0.0, 1.0, 0.0), 24, "env")
    inside = sphere_normals(24)[1]
    np.testing.assert_allclose(img[inside], np.broadcast_to([0.5, 0.3, 0.1], img[inside].shape), rtol=0.01)


def test_slice_convention():
    wi, wo = slice_directions(30.0, [-30.0, 30.0, 0.0])
    np.testing.assert_allclose(wo[0], wi[0], atol=1e-12)                     # back to the light
    np.testing.assert_allclose(wo[1], [-wi[1][0], 0.0, wi[1][2]], atol=1e-12)  # mirror direction
    _, wo = slice_directions(30.0, [45.0], 90.0)
    assert abs(wo[0, 0]) < 1e-12 and wo[0, 1] > 0


def test_written_files(metal, tmp_path):
    import xml.etree.ElementTree as ET

    import OpenEXR
    from matplotlib.image import imread
    table, model, params = metal
    paths, captions = write_images(tmp_path, NAME, table, model, params, lights=DEFAULT_LIGHTS[:1], size=48)
    paths += write_slices(tmp_path / "direct", NAME, table, model, params)
    assert {p.name for p in paths} == {f"{NAME}-sphere-key.png", f"{NAME}-sphere-key.exr", f"{NAME}-thumb.png",
                                       f"{NAME}-slices.svg", f"{NAME}-lobes.svg"}
    for p in paths:
        assert p.stat().st_size > 2000, p
        if p.suffix == ".png":
            img = imread(p)
            assert img.ndim == 3 and img[..., :3].std() > 0.01, p
        if p.suffix == ".svg":
            root = ET.parse(p).getroot()
            assert root.tag.endswith("svg") and len(root.findall(".//{*}path")) > 20, p
    assert "median relative difference" in captions[f"{NAME}-sphere-key.png"]
    assert imread(tmp_path / f"{NAME}-thumb.png").shape[:2] == (96, 192)
    with OpenEXR.File(str(tmp_path / f"{NAME}-sphere-key.exr"), separate_channels=True) as f:
        ch = f.channels()
        assert {"A", "measured.R", "fitted.G", "difference.B"} <= set(ch)
        assert ch["fitted.R"].pixels.shape == (48, 48)
    assert not list(tmp_path.rglob("*.tmp*"))


def test_plan_shows_what_the_direct_renderers_show(metal):
    """The report's plan: point-lit spheres and slices are the direct renderings' values; the
    environment sphere (the table's bins, for measurement and fit alike) is close to the exact one."""
    table, model, params = metal
    values = np.array([params[n] for n in model.names])
    brdf = np.ascontiguousarray(table.brdf().T).T
    p = plan(DEFAULT_LIGHTS, 40, 24)
    fitted = Evaluator(p, model)([values])[0]
    at_points, at_env = p.measured(p.table_values(brdf))
    meas, fit = p.images(at_points, at_env), p.images(fitted.points, fitted.env)
    for label, kind, d in DEFAULT_LIGHTS:
        size = 24 if kind == "env" else 40
        exact, looked_up = render_model_sphere(model, values, d, size, kind), render_table_sphere(brdf, d, size, kind)
        assert np.array_equal(np.isnan(exact).all(-1), np.isnan(fit[label]).all(-1))
        ok = np.isfinite(exact) & (exact > 1e-6)
        rel = np.abs(fit[label][ok] / exact[ok] - 1)
        if kind == "point":
            assert rel.max() < 1e-9, label
            np.testing.assert_allclose(meas[label], looked_up, rtol=1e-12, equal_nan=True)
        else:
            assert np.median(rel) < 0.02, (label, np.median(rel))
    direct = slice_curves(brdf, model, values)
    for key, cv in curves(p, at_points, fitted).items():
        for k in cv:
            np.testing.assert_allclose(cv[k], direct[key][k], rtol=1e-9, atol=1e-300, err_msg=f"{key} {k}")


def test_engine_values_match_the_reference(metal):
    from brdfcl.device.engine import Engine
    table, model, params = metal
    values = np.array([params[n] for n in model.names])
    p = plan(DEFAULT_LIGHTS, 40, 24)
    ref = Evaluator(p, model)([values])[0]
    got = Evaluator(p, model, Engine(model))([values, values])
    for f in got:
        np.testing.assert_allclose(f.points, ref.points, rtol=2e-5)
        np.testing.assert_allclose(f.env, ref.env, rtol=2e-5)
        for k in ref.lobes:
            np.testing.assert_allclose(f.lobes[k], ref.lobes[k], rtol=2e-5, atol=1e-30)


def _largest_offset(x, y, keep):
    """The largest distance of a point of the line (x, y) from the line through its kept points."""
    seg = np.searchsorted(keep, np.arange(x.size), side="right") - 1       # the kept chord over each point
    a, b = keep[np.minimum(seg, keep.size - 2)], keep[np.minimum(seg + 1, keep.size - 1)]
    dx, dy = x[b] - x[a], y[b] - y[a]
    return (np.abs(dx * (y - y[a]) - dy * (x - x[a])) / np.hypot(dx, dy)).max()


def test_thinned_lines_stay_within_the_tolerance():
    x = np.linspace(0, 300, 721)
    y = 100 + 60 * np.sin(x / 17.0) + 40 * np.exp(-((x - 150) / 2.0) ** 2)
    keep = _thin(x, y)
    assert keep[0] == 0 and keep[-1] == x.size - 1 and keep.size < x.size / 2
    assert _largest_offset(x, y, keep) < TOLERANCE_PX


def test_runs_thinned_together_keep_their_ends_and_the_tolerance():
    x = np.linspace(0, 300, 721)
    y = 100 + 60 * np.sin(x / 17.0) + 40 * np.exp(-((x - 150) / 2.0) ** 2)
    starts, stops = np.array([0, 3, 200, 201, 500]), np.array([2, 150, 201, 480, 721])
    keep, run_of = _thin_runs(x, y, starts, stops)
    assert keep.size < x.size / 2 and np.all(np.diff(run_of) >= 0)
    for i, (a, b) in enumerate(zip(starts, stops)):
        mine = keep[run_of == i]
        assert mine[0] == a and mine[-1] == b - 1
        assert b - a < 3 or _largest_offset(x[a:b], y[a:b], mine - a) < TOLERANCE_PX


def test_markers_are_drawn_at_each_valid_point():
    import xml.etree.ElementTree as ET
    fig = Figure(2, 2)
    x = np.linspace(-90, 90, 13)
    y = np.exp(-x / 50)
    y[[2, 7]] = [np.nan, 0.0]                     # not drawn
    for c in range(2):
        p = fig.panel(0, c, x_range=(-90, 90), y_range=(1e-2, 10))
        p.markers(x, y, "#123456")
        p.markers(x[:4], y[:4], "#654321", radius=3)
    lone = fig.panel(1, 0, x_range=(-90, 90), y_range=(1e-2, 10))
    lone.markers(x[2:4], y[2:4], "#123456")         # one valid point: a path of two vertices there
    ns = {"s": "http://www.w3.org/2000/svg"}
    root = ET.fromstring(fig.svg())
    markers = {m.get("id"): m.find("s:circle", ns) for m in root.iter("{http://www.w3.org/2000/svg}marker")}
    assert sorted((c.get("stroke"), c.get("r")) for c in markers.values()) == [("#123456", "22"), ("#654321", "30")]
    paths = [p for p in root.iter("{http://www.w3.org/2000/svg}path") if p.get("marker-mid")]
    assert len(paths) == 5 and all(p.get("marker-start") == p.get("marker-mid") == p.get("marker-end") for p in paths)
    single = np.array(paths[-1].get("d")[1:].split(), dtype=float).reshape(-1, 2)
    assert len(single) == 2 and np.array_equal(single[0], single[1])
    for p in paths[:-1]:
        assert p.get("marker-mid")[5:-1] in markers and p.get("stroke") == "none"
        xy = np.array(p.get("d")[1:].split(), dtype=float).reshape(-1, 2) / 10
        n = 11 if markers[p.get("marker-mid")[5:-1]].get("stroke") == "#123456" else 3
        assert len(xy) == n and np.all(np.diff(xy[:, 0]) > 0)


def test_lobes_add_up(metal):
    table, model, params = metal
    values = np.array([params[n] for n in model.names])
    cv = slice_values(table, model, values, 30.0, np.arange(-80.0, 81.0, 10.0), lobes=True)
    assert set(cv) == {"measured", "fitted", "diffuse", "diffraction", "ct"}
    np.testing.assert_allclose(cv["diffuse"] + cv["diffraction"] + cv["ct"], cv["fitted"], rtol=1e-12)


@pytest.mark.parametrize("interp", ["log", "linear"])
def test_interpolate_matches_the_full_rule(interp):
    """Points whose corners are all present take the quick path; the result is the full rule's
    (missing corners left out, non-positive ones interpolated linearly) at every point."""
    rng = np.random.default_rng(3)
    wi = sphere._unit(0.3, 0.2, 0.9) * np.ones((4000, 1))
    wo = rng.normal(size=(4000, 3))
    wo[:, 2] = np.abs(wo[:, 2])
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    index, weight = corners(wi, wo)
    cells = np.unique(index)
    brdf = rng.uniform(0.01, 2.0, size=(3, cells.size))
    brdf[0, ::37] = np.nan                 # missing cells
    brdf[1, ::53] = 0.0                    # a value the log cannot take
    brdf[2, ::71] = -1.0
    where = (np.searchsorted(cells, index), weight)
    brdf[0, where[0][:, 0]] = np.nan       # every corner of the first point: NaN there
    got = interpolate(brdf, where, interp)
    want = _interpolate(brdf, *where, interp)
    assert np.isnan(got[0, 0]) and np.isfinite(got[1:, 0]).all()
    touched = (~np.isfinite(brdf) | (brdf <= 0)).any(0)[where[0]].any(0)
    assert 0.05 < touched.mean() < 0.95     # both paths taken
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
