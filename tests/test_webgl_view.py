"""The live view on a material's page (brdfcl.report.view.webgl): its GLSL ES compiles, its
uniforms and sliders are the model's parameters, and in headless Chromium (software WebGL) it
draws the lit sphere brdfcl draws itself.

The fast tier reads written pages: the fragment shader (as shown and with ``VALUES``) of every
demo model and of both forms the default fit chooses between goes through glslangValidator
(Debian's glslang-tools) as GLSL ES 3.00.  The slow tier loads pages of the demo truths beside
their tables in Chromium with SwiftShader and reads back the canvas and the shader's linear
values; each check skips with a reason when its tool is missing."""
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from brdfcl.model.compose import DEFAULT_MODEL, Model
from brdfcl.model.synth import DEMO, demo_values
from brdfcl.optim.forms import DEFAULT_FORMS, form_keys
from brdfcl.report.export.brdf_explorer import uniform_name
from brdfcl.report.export.fitfile import fit_document
from brdfcl.report.export.glsl_es import to_glsl_es
from brdfcl.report.view.pages import Entry, material_page, write_report
from brdfcl.report.view.sphere import render_model_sphere

# -n with --dist loadgroup (the slow tier in .ci/run): one process runs this module's tests, not
# one after another, so its costly fixture is session-scoped: made once there
pytestmark = pytest.mark.xdist_group("test_webgl_view")

GLSLANG = shutil.which("glslangValidator")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
SPECS = sorted({spec for spec, _ in DEMO.values()} | set(form_keys(DEFAULT_MODEL, DEFAULT_FORMS).values()))
VIEW_UNIFORMS = {"u_size", "u_light", "u_scale", "u_mode", "u_theta_i"}


def _entry(spec, name="m", table=None):
    model = Model(spec)
    params = next((p for s, p in DEMO.values() if s == spec), {})
    doc = {"errors": {}, "status": "truth", **fit_document(model, demo_values(model, params), name)}
    return Entry.from_document(doc, table, tabulated=table is not None), model


def _shader(page):
    return re.search(r"<script type='x-shader/x-fragment' id='brdfcl-fs'>(.*?)</script>", page, re.S).group(1)


def _config(page):
    return json.loads(re.search(r"<script type='application/json' id='brdfcl-view-config'>(.*?)</script>",
                                page, re.S).group(1))


@pytest.mark.skipif(GLSLANG is None, reason="glslangValidator not installed (apt-get install glslang-tools)")
@pytest.mark.parametrize("spec", SPECS)
def test_page_shader_is_valid_glsl_es(tmp_path, spec):
    e, _ = _entry(spec)
    page = material_page(e, {}, tmp_path)
    src = _shader(page)
    assert src.startswith("#version 300 es\n")
    for variant, text in (("show", src), ("values", src.replace("\n", "\n#define VALUES\n", 1))):
        f = tmp_path / f"{variant}.frag"
        f.write_text(text)
        r = subprocess.run([GLSLANG, str(f)], capture_output=True, text=True)
        assert r.returncode == 0, (variant, r.stdout[-3000:] + r.stderr[-2000:])


@pytest.mark.parametrize("spec", SPECS)
def test_uniforms_and_sliders_are_the_parameters(tmp_path, spec):
    e, model = _entry(spec)
    page = material_page(e, {}, tmp_path)
    cfg, src = _config(page), _shader(page)
    declared = [n for n in re.findall(r"^uniform float (\w+);", src, re.M) if n not in VIEW_UNIFORMS]
    assert declared == [uniform_name(s.name) for s in model.slots]
    assert set(re.findall(r"^uniform \w+ (\w+);", src, re.M)) - set(declared) == VIEW_UNIFORMS
    assert [q["u"] for q in cfg["params"]] == declared
    for q, s in zip(cfg["params"], model.slots):
        assert q["name"] == s.name and q["lo"] == s.param.lo and q["hi"] == s.param.hi
        assert q["log"] == bool(s.param.log) and q["value"] == pytest.approx(e.params[s.name])
    for control in ("brdfcl-theta", "brdfcl-phi", "brdfcl-ti", "brdfcl-stops"):
        assert f"id='{control}' type='range'" in page
    # no table: the page says the measured view is not there, in one sentence
    assert "Measured view: not available (no measurement with this fit)" in page


def test_desktop_glsl_is_refused():
    with pytest.raises(ValueError, match="double"):
        to_glsl_es("double f(double x) { return x; }", [])


def test_turntable_is_the_table_sphere(demo_db):
    """The measured spheres beside the live view (each computed on its upper half, mirrored) are
    brdfcl's table sphere at their light."""
    from brdfcl.data.merl import read_merl
    from brdfcl.report.view.images import PLAN
    from brdfcl.report.view.sphere import render_table_sphere
    from brdfcl.report.view.views import plan
    from brdfcl.report.writers.pages import _read_cells
    p, path = plan(*PLAN), str(demo_db / "synth-rough-metal.binary")
    images = p.turntable_images(_read_cells(path, p.table_cells))
    table = read_merl(path)
    for k in (0, 3, 8):
        t = np.radians(float(p.turntable[k].label))
        ref = render_table_sphere(table, [np.sin(t), 0.0, np.cos(t)], size=p.turntable[k].size)
        assert np.array_equal(np.isnan(images[k]), np.isnan(ref))
        ok = np.isfinite(ref) & (ref > 0)
        assert np.max(np.abs(images[k][ok] - ref[ok]) / ref[ok]) < 1e-4


# --- in a browser ------------------------------------------------------------------------------
PROBE = """<script>window.addEventListener('load', function () {
  var out = {};
  try {
    var v = window.brdfclView.sphere(SIZE, 45, 135), vals = [];
    for (var i = 0; i < v.f.length; i += 4) vals.push(v.f[i], v.f[i + 1], v.f[i + 2]);
    out.values = vals.map(function (x) { return +x.toPrecision(6); });
    var c = document.getElementById('brdfcl-fit'), s = document.createElement('canvas');
    s.width = c.width; s.height = c.height;
    var g = s.getContext('2d');
    g.drawImage(c, 0, 0);
    out.pixels = Array.prototype.slice.call(g.getImageData(0, 0, c.width, c.height).data);
    out.size = c.width;
    var m = document.getElementById('brdfcl-measured');
    out.measured = m ? m.style.backgroundPosition + ' ' + m.style.transform : null;
    out.note = document.getElementById('brdfcl-view-note').textContent;
  } catch (e) { out.error = String(e); out.note = document.getElementById('brdfcl-view-note').textContent; }
  var p = document.createElement('pre');
  p.id = 'probe';
  p.textContent = JSON.stringify(out);
  document.body.appendChild(p);
});</script>"""
SIZE = 48


@pytest.fixture(scope="session")
def pages(demo_db, tmp_path_factory):
    from brdfcl.report.writers.pages import _read_cells
    out = tmp_path_factory.mktemp("webgl")
    entries = [_entry(spec, name, str(demo_db / f"{name}.binary"))[0] for name, (spec, _) in DEMO.items()]
    write_report(out, entries, _read_cells)
    return out / "report"


def _probe(page):
    probe = page.with_name(f".probe-{page.name}")
    probe.write_text(page.read_text() + PROBE.replace("SIZE", str(SIZE)))
    r = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--use-angle=swiftshader",
                        "--enable-unsafe-swiftshader", "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()],
                       capture_output=True, text=True, timeout=180)
    probe.unlink()
    found = re.search(r'<pre id="probe">(.*?)</pre>', r.stdout, re.S)
    assert found, r.stderr[-2000:]
    import html
    return json.loads(html.unescape(found.group(1)))


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium (apt-get install chromium); .ci/run installs it")
@pytest.mark.parametrize("name", ["synth-smooth-plastic", "synth-rough-metal"])
def test_chromium_draws_the_lit_sphere_brdfcl_draws(pages, name):
    out = _probe(pages / f"{name}.html")
    assert "error" not in out and not out["note"], out
    n = out["size"]
    px = np.array(out["pixels"], dtype=float).reshape(n, n, 4)[..., :3]   # row 0 at the top
    c = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(c, -c)
    r2 = x * x + y * y
    lum = px.mean(-1)
    assert np.all(lum[r2 > 1.02] == 0), "not black off the sphere"
    inside = r2 < 0.98
    assert np.mean(lum[inside] > 0) > 0.5, "the lit half of the sphere is dark"
    toward = inside & (x < 0) & (y > 0)          # the light is from the upper left (azimuth 135 deg)
    away = inside & (x > 0) & (y < 0)
    assert lum[toward].mean() > 2 * lum[away].mean()
    # the shader's linear values against brdfcl's float64 sphere at the same light
    spec, params = DEMO[name]
    model = Model(spec)
    ref = render_model_sphere(model, demo_values(model, params), [-0.5, 0.5, np.sqrt(0.5)], size=SIZE)
    got = np.array(out["values"]).reshape(SIZE, SIZE, 3)[::-1]               # GL rows: bottom first
    ok = np.isfinite(ref) & (ref > 1e-6 * np.nanmax(ref))
    rel = np.abs(got[ok] - ref[ok]) / ref[ok]
    assert np.median(rel) < 1e-3, (name, float(np.median(rel)), float(np.percentile(rel, 95)))
    print(f"{name}: WebGL sphere against brdfcl's, median relative difference {np.median(rel):.2e}")
    # the measured turntable beside it: the 45 deg frame (the 4th of 12), turned to azimuth 135 deg
    assert out["measured"] and "rotate(-135deg)" in out["measured"], out["measured"]
