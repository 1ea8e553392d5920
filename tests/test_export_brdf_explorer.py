"""BRDF Explorer export: the .brdf file has BRDF Explorer's sections and every parameter as a
slider, and its GLSL, generated from the OpenCL kernel sources, computes Model.reference.

The GLSL is checked numerically by compiling the shader section as C++ (g++, a minimal vec3 and
`out` parameters as references), in float (with -fsingle-precision-constant, GLSL's float
semantics) and in double, on random direction pairs; and for syntax with glslangValidator
(Debian's glslang-tools) as a GLSL 4.10 fragment shader, BRDF Explorer's version.  Each check
skips with a reason when its compiler is missing."""
import json
import re
import shutil
import subprocess
import zlib

import numpy as np
import pytest

from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.synth import DEMO, demo_values
from brdfcl.report.export.brdf_explorer import brdf_explorer_text, cl_to_glsl, write_brdf_explorer
from brdfcl.report.export.fitfile import fit_document

# Together these use every kernel file: each NDF, G, Fresnel and PSD.
SPECS = ["diffuse+diffraction:hp+ggx:smith:schlick",
         "diffraction:abc:dielectric+beckmann:smith-hc:conductor",
         "diffuse+diffraction:gauss:schlick+sgd:vcavity:none",
         "epd:none:dielectric",
         "ggx:smith-hc:conductor",
         "diffuse+beckmann:smith:schlick",
         "diffuse+diffraction:hp:none+abc:smith:schlick",     # the default fit's forms (ABC's Smith
         "diffuse+diffraction:hp:none+gtr:smith:dielectric"]  # term casts a negative literal)


def _values(model, rng):
    """Parameters spread over each one's search range (log-uniform where log), not defaults."""
    out = []
    for s in model.slots:
        lo, hi = s.param.search_range
        if s.param.name == "alpha" or s.param.name == "beta":
            lo, hi = 0.02, 0.5
        u = rng.random()
        out.append(np.exp(np.log(lo) + u * (np.log(hi) - np.log(lo))) if s.param.log
                   else lo + u * (hi - lo))
    return np.array(out)


def _sections(text):
    lines = text.splitlines()
    assert lines[0].split()[0] == "analytic"
    b, e = lines.index("::begin parameters"), lines.index("::end parameters")
    bs, es = lines.index("::begin shader"), lines.index("::end shader")
    assert b < e < bs < es
    params = [ln.split() for ln in lines[b + 1:e] if ln.strip() and not ln.lstrip().startswith("#")]
    return params, "\n".join(lines[bs + 1:es])


def test_file_has_sections_and_every_parameter(tmp_path):
    spec, p = DEMO["synth-smooth-metal"]
    model = Model(spec)
    values = demo_values(model, p)
    src = tmp_path / "synth-smooth-metal.json"
    src.write_text(json.dumps(fit_document(model, values, "synth-smooth-metal")))
    out = write_brdf_explorer(tmp_path / "m.brdf", src)
    text = out.read_text()
    params, shader = _sections(text)
    assert [q[1] for q in params] == [n.replace(".", "_") for n in model.names]
    for q, s, v in zip(params, model.slots, values):
        assert q[0] == "float" and len(q) == 5
        lo, hi, default = map(float, q[2:])
        assert lo == pytest.approx(s.param.lo) and hi == pytest.approx(s.param.hi)
        assert default == pytest.approx(v, rel=1e-8) and lo <= default <= hi
    assert re.search(r"vec3 BRDF\(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y\)", shader)
    # BRDF Explorer drops lines starting with '#', even in the shader: there must be none
    assert not [ln for ln in shader.splitlines() if ln.lstrip().startswith("#")]
    # the document and the path give the same file
    assert brdf_explorer_text(json.loads(src.read_text())) == text


def test_translation_of_opencl_constructs():
    src = """inline real_v f(const cell_t *c, real a, real_v *d_a)
{
    real_v di;
    const real_v x = SEL(c->sh, (real_v)2, fmin(c->ch, (real)0.5) < 1);
    *d_a = 3 * x + log1p(x) + erfc(a) * 1e-05;
    return g(&di, x);
}"""
    out = cl_to_glsl(src)
    assert "float f(cell_t c, float a, out float d_a)" in out
    assert "float x = ((min(c.ch, float(0.5)) < 1.0) ? (float(2.0)) : (c.sh));" in out
    assert "d_a = 3.0 * x + brdfcl_log1p(x) + brdfcl_erfc(a) * 1e-05;" in out
    assert "return g(di, x);" in out


_CPP_HEAD = r"""
#include <cmath>
#include <cstdio>
#include <algorithm>
using namespace std;
struct vec3 {
    float x, y, z;
    vec3(float a = 0) : x(a), y(a), z(a) {}
    vec3(float a, float b, float c) : x(a), y(b), z(c) {}
};
static vec3 operator+(vec3 a, vec3 b) { return vec3(a.x + b.x, a.y + b.y, a.z + b.z); }
static float dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static vec3 cross(vec3 a, vec3 b)
{ return vec3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x); }
static float length(vec3 a) { return sqrt(dot(a, a)); }
static vec3 normalize(vec3 a) { float l = length(a); return vec3(a.x / l, a.y / l, a.z / l); }
"""

_CPP_MAIN = r"""
int main() {
    float a, b, c, d, e, f;
    while (scanf(SCAN, &a, &b, &c, &d, &e, &f) == 6) {
        vec3 r = BRDF(vec3(a, b, c), vec3(d, e, f), vec3(0, 0, 1), vec3(1, 0, 0), vec3(0, 1, 0));
        printf("%.17g %.17g %.17g\n", (double)r.x, (double)r.y, (double)r.z);
    }
    return 0;
}
"""


def _as_cpp(text, real):
    params, shader = _sections(text)
    body = re.sub(r"\bout\s+(\w+)\s+(\w+)", r"\1 &\2", shader)     # GLSL out parameters
    decl = "\n".join(f"static float {q[1]} = {q[4]};" for q in params)
    src = _CPP_HEAD + decl + "\n" + body + _CPP_MAIN.replace("SCAN", '"%f %f %f %f %f %f"')
    if real == "double":
        src = re.sub(r"\bfloat\b", "double", src).replace('"%f %f', '"%lf %lf').replace(
            '%f %f %f %f"', '%lf %lf %lf %lf"')
    return src


def _directions(rng, n):
    def hemi(k):
        z = rng.uniform(0.03, 1.0, k)
        ph = rng.uniform(0, 2 * np.pi, k)
        r = np.sqrt(1 - z * z)
        return np.stack([r * np.cos(ph), r * np.sin(ph), z], -1)
    wi = hemi(n)
    wo = hemi(n)
    # a quarter near the mirror direction, where the peaks are
    k = n // 4
    mir = wi[:k] * [-1, -1, 1]
    wo[:k] = mir + rng.normal(0, 0.02, (k, 3))
    wo[:k, 2] = np.abs(wo[:k, 2]) + 0.03
    wo /= np.linalg.norm(wo, axis=-1, keepdims=True)
    return wi, wo


@pytest.mark.skipif(shutil.which("g++") is None, reason="g++ not installed: the GLSL is checked as C++")
@pytest.mark.parametrize("spec", SPECS)
@pytest.mark.parametrize("real,rtol", [("double", 2e-6), ("float", 1e-4)])
def test_shader_computes_the_reference(tmp_path, spec, real, rtol):
    rng = np.random.default_rng(zlib.crc32(spec.encode()))
    model = Model(spec)
    values = _values(model, rng)
    text = brdf_explorer_text(fit_document(model, values, "t"))
    cpp = tmp_path / "brdf.cpp"
    cpp.write_text(_as_cpp(text, real))
    exe = tmp_path / "brdf"
    flags = ["-fsingle-precision-constant"] if real == "float" else []
    r = subprocess.run(["g++", "-O1", "-w", *flags, "-o", str(exe), str(cpp)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    wi, wo = _directions(rng, 2000)
    inp = "\n".join(" ".join(f"{x:.9g}" for x in np.concatenate([a, b])) for a, b in zip(wi, wo))
    r = subprocess.run([str(exe)], input=inp, capture_output=True, text=True, timeout=60)
    got = np.loadtxt(r.stdout.splitlines()).T
    # the reference at the directions the program read (rounded to 9 digits, as it saw them)
    back = np.array([[float(x) for x in ln.split()] for ln in inp.splitlines()])
    ref = model.reference(Cells.from_directions(back[:, :3], back[:, 3:]), values, jacobian=False)
    assert np.all(np.isfinite(got))
    # float: exp() of large exponents (EPD, Beckmann tails) amplifies float32 rounding, so values
    # far below the channel's peak are held to 1e-6 of it instead
    floor = (1e-6 if real == "float" else 1e-12) * np.max(np.abs(ref), axis=1, keepdims=True)
    rel = np.abs(got - ref) / np.maximum(np.abs(ref), floor)
    assert np.max(rel) < rtol, (spec, real, float(np.max(rel)), float(np.median(rel)))
    print(f"{spec} {real}: max relative difference {np.max(rel):.2e}")


@pytest.mark.skipif(shutil.which("glslangValidator") is None,
                    reason="glslangValidator not installed (apt-get install glslang-tools)")
@pytest.mark.parametrize("spec", SPECS)
def test_shader_is_valid_glsl_410(tmp_path, spec):
    model = Model(spec)
    text = brdf_explorer_text(fit_document(model, model.defaults(), "t"))
    params, shader = _sections(text)
    # as BRDF Explorer's templates wrap it: version, uniforms, the BRDF, then its use
    call = ("BRDF(vec3(0.0, 0.6, 0.8), vec3(0.0, 0.0, 1.0), vec3(0.0, 0.0, 1.0), "
            "vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0))")
    frag = ("#version 410\n" + "".join(f"uniform float {q[1]};\n" for q in params) + shader
            + f"\nout vec4 fragColor;\nvoid main(void)\n{{\n    fragColor = vec4({call}, 1.0);\n}}\n")
    f = tmp_path / "brdf.frag"
    f.write_text(frag)
    r = subprocess.run(["glslangValidator", str(f)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
