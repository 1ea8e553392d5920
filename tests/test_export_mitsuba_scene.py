"""Mitsuba 3 scene files of a fit (brdfcl.report.export.mitsuba_scene, ``brdfcl export --mitsuba``).

The mapping onto Mitsuba's own BSDFs is checked twice: in float64, against brdfcl's reference
(Mitsuba's formulas written out, which must be the fit's where the mapping says exact), and by
rendering both with Mitsuba (skipped without the extra, or without an LLVM Dr.Jit can use)."""
import json
import runpy
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.report.export.fitfile import fit_document
from brdfcl.report.export.mitsuba_scene import _builtin_reference, _directions, builtin_mapping, write_mitsuba
from tests.mitsuba_scenes import LIGHT, disc, relative_difference, render, sphere_scene, use_variant

EXACT = ["diffuse+ggx:smith:conductor", "diffuse+ggx:smith:dielectric", "ggx:smith:none", "ggx:smith:conductor"]
APPROXIMATE = ["diffuse+beckmann:smith:schlick", "diffuse+ggx:smith-hc:conductor", "diffuse+ggx:smith:schlick"]
NONE = {"diffuse+diffraction+ggx": "diffraction", "diffuse+gtr:smith:dielectric": "gtr",
        "diffuse+ggx:vcavity:conductor": "vcavity", "diffuse+ggx+ggx": "two lobes"}


def _values(spec, rho_s=1.6):
    """Defaults, with a specular amplitude above 1 (Mitsuba's reflectance limit) where there is one."""
    m = Model(spec)
    v = m.defaults()
    for i, s in enumerate(m.slots):
        if s.name.startswith("ct.rho"):
            v[i] = rho_s * (1 - 0.2 * s.channel)
        if s.name.startswith("diffuse.rho"):
            v[i] = 0.1 + 0.05 * s.channel
    return m, v


@pytest.mark.parametrize("spec", EXACT)
def test_exact_mappings_are_the_fit_in_float64(spec):
    m, v = _values(spec)
    mp = builtin_mapping(m, v)
    assert mp.exact and mp.note.startswith("exact"), mp.note
    cells = Cells.from_directions(*_directions())
    np.testing.assert_allclose(_builtin_reference(mp.bsdf, cells), m.reference(cells, v, jacobian=False),
                               rtol=1e-12, atol=0)


@pytest.mark.parametrize("spec", APPROXIMATE)
def test_approximate_mappings_state_their_difference(spec):
    m, v = _values(spec)
    mp = builtin_mapping(m, v)
    assert not mp.exact and mp.bsdf is not None
    cells = Cells.from_directions(*_directions())
    f, g = m.reference(cells, v, jacobian=False), _builtin_reference(mp.bsdf, cells)
    stated = float(mp.note.split("differs by up to ")[1].split("%")[0])
    ok = f > 1e-12 * f.max()
    assert stated == pytest.approx(100 * np.max(np.abs(g[ok] - f[ok]) / f[ok]), rel=0.05)
    assert stated > 0


@pytest.mark.parametrize("spec, why", NONE.items())
def test_fits_without_a_builtin_counterpart_say_why(spec, why):
    m, v = _values(spec)
    mp = builtin_mapping(m, v)
    assert mp.bsdf is None and why in mp.note, mp.note


def test_files_written_parse_and_load_as_python(tmp_path):
    m, v = _values("diffuse+ggx:smith:conductor")
    fit = tmp_path / "fits" / "brass.json"
    fit.parent.mkdir()
    fit.write_text(json.dumps(fit_document(m, v, "brass")))
    out = tmp_path / "mitsuba"
    written = {p.name for p in write_mitsuba(out, fit)[0]}
    assert written == {"brass.json", "brass.xml", "brass-scene.xml", "brass-builtin.xml", "brass-builtin-scene.xml",
                       "brass.py", "brass-reflectance.exr", "brass-specular_reflectance.exr"}
    for name in written - {"brass.json", "brass.py"} - {n for n in written if n.endswith(".exr")}:
        ET.parse(out / name)                                   # well-formed XML
    frag = ET.parse(out / "brass-builtin.xml").getroot()
    assert frag.find("bsdf").get("id") == "brass-builtin"
    d = runpy.run_path(str(out / "brass.py"))
    assert d["BSDF"] == {"type": "brdfcl", "fit": str(out / "brass.json")}
    assert d["BUILTIN"]["type"] == "blendbsdf" and d["BUILTIN_NOTE"].startswith("exact")
    # amplitudes above 1 travel as 1 x 1 EXR textures, with the values the mapping holds
    import OpenEXR
    with OpenEXR.File(str(out / "brass-specular_reflectance.exr"), separate_channels=True) as f:
        rgb = [float(f.channels()[c].pixels[0, 0]) for c in "RGB"]
    np.testing.assert_allclose(rgb, builtin_mapping(m, v).bsdf["bsdf_1"]["specular_reflectance"]["value"], rtol=1e-6)
    assert json.loads((out / "brass.json").read_text())["model"] == m.spec


def test_cli_export_mitsuba(tmp_path):
    m, v = _values("diffuse+ggx:smith:dielectric")
    fit = tmp_path / "plastic.json"
    fit.write_text(json.dumps(fit_document(m, v, "plastic")))
    run = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "export", str(fit), "--mitsuba", str(tmp_path / "m")],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "Mitsuba's own BSDFs: exact" in run.stdout
    assert (tmp_path / "m" / "plastic-builtin-scene.xml").exists()
    run = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "export", str(fit)], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode != 0 and "--mitsuba DIR" in run.stderr and len(run.stderr.splitlines()) == 1


def test_one_channel_fits_and_other_fits_in_the_folder_are_refused(tmp_path):
    m = Model("diffuse+ggx:smith:conductor", lambdas=(0.55,))
    mp = builtin_mapping(m, m.defaults())
    assert mp.bsdf is None and "a fit of 1 channel " in mp.note
    with pytest.raises(ValueError, match=r"a fit of 1 channel; .* fits of 3 \(R, G, B\)"):
        write_mitsuba(tmp_path / "m", fit_document(m, m.defaults(), "grey"))
    rgb, v = _values("diffuse+ggx:smith:conductor")
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "brass.json").write_text(json.dumps(fit_document(rgb, v * 1.01, "brass")))
    with pytest.raises(ValueError, match="holds another fit"):
        write_mitsuba(tmp_path / "m", fit_document(rgb, v, "brass"))
    # the fit's own folder: its NAME.json is left as it is
    own = tmp_path / "m" / "brass.json"
    before = own.read_text()
    written, _ = write_mitsuba(tmp_path / "m", own)
    assert own.read_text() == before and own not in written


def test_a_part_that_reflects_nothing_is_left_out():
    m, v = _values("diffuse+ggx:smith:conductor")
    v[[m.column(f"diffuse.rho_{c}") for c in "rgb"]] = 0.0
    bsdf = builtin_mapping(m, v).bsdf
    assert bsdf["type"] == "roughconductor"
    cells = Cells.from_directions(*_directions())
    np.testing.assert_allclose(_builtin_reference(bsdf, cells), m.reference(cells, v, jacobian=False), rtol=1e-12)


def test_the_formulas_written_as_mitsubas_are_mitsubas():
    """What _builtin_reference takes Mitsuba to compute (D, Smith G1, conductor Fresnel), against
    Mitsuba's own functions in scalar_rgb."""
    mi = pytest.importorskip("mitsuba", reason='Mitsuba 3 not installed: pip install "brdfcl[mitsuba]"')
    import drjit as dr

    from brdfcl.model.terms import REGISTRY
    from brdfcl.report.export.mitsuba_scene import _walter_g1
    mi.set_variant("scalar_rgb")
    rng = np.random.default_rng(1)
    for _ in range(40):
        wi, wo = rng.normal(size=(2, 3))
        wi[2], wo[2] = abs(wi[2]) + 0.1, abs(wo[2]) + 0.1
        wi, wo = wi / np.linalg.norm(wi), wo / np.linalg.norm(wo)
        c = Cells.from_directions(wi[None], wo[None])
        h = (wi + wo) / np.linalg.norm(wi + wo)
        m, v = mi.Vector3f(*map(float, h)), mi.Vector3f(*map(float, wi))
        for kind, a in (("ggx", 0.07), ("beckmann", 0.3)):
            d = mi.MicrofacetDistribution(getattr(mi.MicrofacetType, kind.upper() if kind == "ggx" else "Beckmann"),
                                          a, sample_visible=False)
            D = REGISTRY["ndf"][kind].reference(c, alpha=a)[0][0]
            assert float(d.eval(m)) == pytest.approx(D, rel=2e-5)
            g1 = (REGISTRY["shadowing"]["smith_ggx"].reference(
                Cells(c.sh, c.ch, c.cd, c.ci, np.ones(1)), alpha=a)[0][0] if kind == "ggx"
                else _walter_g1(a, c.t2i)[0])
            assert float(d.smith_g1(v, m)) == pytest.approx(g1, rel=2e-5, abs=1e-7)
        for eta, k in ((1.5, 0.0), (0.2, 3.0), (2.5, 1.2)):
            F = REGISTRY["fresnel"]["conductor"].reference(c, eta=eta, k=k)[0][0]
            assert float(mi.fresnel_conductor(float(c.cd[0]), mi.Complex2f(eta, k))) == pytest.approx(F, rel=2e-5)
    assert dr is not None


@pytest.fixture
def mi():
    return use_variant("llvm_ad_rgb")


@pytest.mark.parametrize("spec", ["diffuse+ggx:smith:conductor", "diffuse+ggx:smith:dielectric",
                                  "diffuse+ggx:smith:schlick", "diffuse+beckmann:smith:conductor",
                                  "diffuse+ggx:smith-hc:conductor"])
def test_builtin_bsdfs_render_as_the_brdfcl_bsdf(mi, tmp_path, spec):
    """Both BSDFs on a sphere under a directional light, the same sample positions: an exact
    mapping agrees to float32 rounding, an approximate one within the difference it states."""
    m, v = _values(spec)
    fit = tmp_path / "x.json"
    fit.write_text(json.dumps(fit_document(m, v, "x")))
    write_mitsuba(tmp_path / "m", fit)
    d = runpy.run_path(str(tmp_path / "m" / "x.py"))
    a, b = (render(mi, sphere_scene(mi, d[k], 64, 4)) for k in ("BSDF", "BUILTIN"))
    rel, lit = relative_difference(a, b)
    print(f"\n{spec}: built-in vs brdfcl BSDF, median relative difference {np.median(rel):.2e}, "
          f"largest {rel.max():.2e} ({d['BUILTIN_NOTE']})")
    if builtin_mapping(m, v).exact:
        assert rel.max() < 1e-4
    else:
        # the stated difference holds for directions to 80 deg: the pixels whose normal is within
        # 80 deg of the view and of the light (the stratified positions: a pixel's normals spread)
        n, _ = disc(64)
        inside = np.repeat(((n[..., 2] > np.cos(np.radians(78))) & (n @ LIGHT > np.cos(np.radians(78))))[..., None],
                           3, -1)
        stated = float(d["BUILTIN_NOTE"].split("differs by up to ")[1].split("%")[0]) / 100
        rel = np.abs(b[lit & inside] - a[lit & inside]) / a[lit & inside]
        assert rel.max() < stated * 1.05 + 1e-4
    for scene in ("x-scene.xml", "x-builtin-scene.xml"):       # the complete scenes load and render
        img = np.array(mi.render(mi.load_file(str(tmp_path / "m" / scene), res=16, spp=4)))
        assert img.shape == (16, 16, 3) and np.isfinite(img).all() and img.max() > 0
