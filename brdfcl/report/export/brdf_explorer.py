"""A fitted model as a Disney BRDF Explorer ``.brdf`` file (its analytic GLSL format).

    from brdfcl.report.export.brdf_explorer import write_brdf_explorer
    write_brdf_explorer("brass.brdf", "fits/brass.json")     # or the parsed NAME.json document

Open the file in BRDF Explorer (File > Open BRDF...).  Each parameter of the model is a slider
(``float NAME MIN MAX DEFAULT``: the parameter's bounds, the fitted value), named as the parameter
with ``.`` replaced by ``_`` (``ct.alpha`` -> ``ct_alpha``).  The shader is not written by hand: it
is generated from the sources the OpenCL kernels are made of (kernels/common.cl, the term files
of the model's lobes and each lobe's emitted expression lines, `brdfcl.kernels.codegen.emit`), at vector
width 1 in float, translated to GLSL 4.10 (the version of BRDF Explorer's shader templates):

* ``real``, ``real_v`` -> ``float``; ``(real)x`` casts -> ``float(x)``; integer literals -> floats;
* pointers: ``const cell_t *c`` -> ``cell_t c``, ``c->`` -> ``c.``, ``real_v *d`` parameters ->
  ``out float d``, ``*d = `` -> ``d = ``, ``&x`` arguments -> ``x``; ``const`` locals lose ``const``
  (GLSL 4.10 wants constant initialisers there); ``inline`` is dropped;
* OpenCL builtins GLSL lacks: ``select`` (the ``SEL`` macro, expanded into ``?:``), ``fmin`` ->
  ``min``, ``log1p`` and ``erfc`` -> helper functions written here (``erfc``: Numerical
  Recipes' Chebyshev fit, relative error < 1.2e-7); ``M_PI``, ``M_1_PI`` -> constants.

BRDF Explorer drops every line that starts with ``#`` (comments), also inside the shader, so the
shader uses no preprocessor directive.  Host constants (the SGD and EPD normalisations) are
written as constants at the fitted values: moving those lobes' shape sliders does not
renormalise them (the file says so).  ``BRDF(L, V, N, X, Y)`` returns f(L, V) in 1/sr per
channel, 0 below the horizon; BRDF Explorer multiplies by N.L itself where it should.
"""
from __future__ import annotations

import os
import re
from functools import lru_cache
from pathlib import Path

import numpy as np

from brdfcl._version import __version__
from brdfcl.kernels.codegen import emit, read_kernel, term_sources
from brdfcl.kernels.terms import cell_source
from brdfcl.model.compose import Model
from brdfcl.report.export.fitfile import load_fit
from brdfcl.report.export.special import erfcc_exponent

GLSL_VERSION = "410"

_HELPERS = f"""\
/* OpenCL builtins that GLSL lacks (brdfcl.report.export.special) */
float brdfcl_log1p(float x)
{{
    float u = 1.0 + x;
    return (u == 1.0) ? x : log(u) * (x / (u - 1.0));
}}

float brdfcl_erfc(float x)
{{
    /* Numerical Recipes' erfcc: relative error < 1.2e-7 everywhere */
    float z = abs(x);
    float t = 1.0 / (1.0 + 0.5 * z);
    float r = t * exp({erfcc_exponent()});
    return (x >= 0.0) ? r : 2.0 - r;
}}

const float PI_R = 3.14159265358979323846;
const float INV_PI_R = 0.318309886183790671538;
"""


def _split_args(s, start):
    """Arguments of the call whose '(' is at s[start]: (list of argument strings, index after ')')."""
    depth, args, cur = 0, [], start + 1
    for i in range(start, len(s)):
        ch = s[i]
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
            if depth == 0:
                args.append(s[cur:i])
                return args, i + 1
        elif ch == "," and depth == 1:
            args.append(s[cur:i])
            cur = i + 1
    raise ValueError("unbalanced parentheses in kernel source")


def _expand_sel(s):
    """SEL(a, b, cond) (OpenCL select: b where cond) -> ((cond) ? (b) : (a))."""
    out, i = [], 0
    for m in re.finditer(r"\bSEL\s*\(", s):
        if m.start() < i:
            continue
        args, end = _split_args(s, m.end() - 1)
        if len(args) != 3:
            raise ValueError(f"SEL with {len(args)} arguments")
        a, b, c = (_expand_sel(x.strip()) for x in args)
        out.append(s[i:m.start()] + f"(({c}) ? ({b}) : ({a}))")
        i = end
    return "".join(out) + s[i:]


_NUM = re.compile(r"(?<![\w.])(\d+\.\d*|\.\d+|\d+)([eE][-+]?\d+)?(?![\w.])")


def _floats(s):
    def fix(m):
        mant, exp = m.group(1), m.group(2) or ""
        return mant + exp if ("." in mant or exp) else mant + ".0"
    return _NUM.sub(fix, s)


_COMMENT = re.compile(r"(/\*.*?\*/|//[^\n]*)", re.S)


def _code_only(fn, src):
    """Apply ``fn`` to the code of ``src``, leaving its comments as they are."""
    parts = _COMMENT.split(src)
    return "".join(p if i % 2 else fn(p) for i, p in enumerate(parts))


def _translate_code(src):
    src = re.sub(r"typedef\s+struct\s*\{", "struct cell_t {", src)
    src = re.sub(r"\}\s*cell_t\s*;", "};", src)
    src = re.sub(r"\binline\s+", "", src)
    src = re.sub(r"\bconst\s+cell_t\s*\*\s*(\w+)", r"cell_t \1", src)
    src = src.replace("->", ".")
    src = re.sub(r"\b(real_v|real)\s*\*\s*(\w+)(?=\s*[,)])", r"out \1 \2", src)   # out parameters
    src = re.sub(r"(^|[;{]\s*)\*(\w+)\s*=", r"\1\2 =", src, flags=re.M)           # *d = ...
    src = re.sub(r"(?<![\w)&\]])&(?=[A-Za-z_])", "", src)                          # &x -> x
    src = _expand_sel(src)
    src = re.sub(r"\((real_v|real)\)\s*(-?\s*(?:\d+\.?\d*(?:[eE][-+]?\d+)?|\w+))", r"\1(\2)", src)
    src = re.sub(r"\((real_v|real)\)\s*\(", r"\1(", src)                             # (real)(x) -> real(x)
    src = re.sub(r"\bconst\s+", "", src)
    src = re.sub(r"\bfmin\s*\(", "min(", src)
    src = re.sub(r"\bfmax\s*\(", "max(", src)
    src = re.sub(r"\blog1p\s*\(", "brdfcl_log1p(", src)
    src = re.sub(r"\berfc\s*\(", "brdfcl_erfc(", src)
    src = re.sub(r"\bM_PI\b", "3.14159265358979323846", src)
    src = re.sub(r"\bM_1_PI\b", "0.318309886183790671538", src)
    src = re.sub(r"\b(real_v|real)\b", "float", src)
    return _floats(src)


def cl_to_glsl(src: str) -> str:
    """Translate brdfcl's OpenCL C (vector width 1) into GLSL (see the module docstring)."""
    # drop the kernel-only preprocessor lines (their meaning is provided by _HELPERS / SEL)
    src = "\n".join(ln for ln in src.splitlines() if not ln.lstrip().startswith("#"))
    src = _code_only(_translate_code, src)
    code = re.sub(r"/\*.*?\*/|//[^\n]*", "", src, flags=re.S)
    left = re.findall(r"\b(select|fmin|fmax|log1p|erfc|cbrt|isnan|__\w+|VLOAD|cond_v)\b"
                      r"|->|\*\s*d_\w+\s*=", code)
    if left:
        raise ValueError(f"OpenCL construct left after translation to GLSL: {sorted(set(left))}")
    return src


def uniform_name(slot_name: str) -> str:
    return slot_name.replace(".", "_")


def _fmt(x: float) -> str:
    return f"{float(x):.9g}"


def shader_source(model, values) -> str:
    """The GLSL of ``vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)`` for a model, its slider
    uniforms being named ``uniform_name(parameter)`` (BRDF Explorer declares them)."""
    head, brdf = _translated(model.spec, tuple(model.lambdas))
    consts = model.consts(np.asarray(values, dtype=np.float64))
    kdecl = [f"const float K_{name.replace('.', '_')} = {_fmt(v)}; "
             "/* host constant at the fitted values (does not follow the sliders) */"
             for name, v in zip(model.const_names, np.atleast_1d(consts))]
    parts = head + (["\n".join(kdecl)] if kdecl else []) + [brdf]
    return "\n\n".join(p.strip("\n") for p in parts) + "\n"


@lru_cache(maxsize=32)
def _translated(spec: str, lambdas: tuple) -> tuple[list[str], str]:
    """What `shader_source` writes that does not depend on the values: the helpers and terms
    translated to GLSL, and the BRDF function; translated once per model (the host constants,
    which depend on the values, go between the two)."""
    model = Model(spec, lambdas=lambdas)
    em = emit(model)
    head = ["/* generated by brdfcl " + __version__ + " from kernels/common.cl, the terms' formulas "
            + "(brdfcl/model/terms) and the lobes' product rule; model "
            + model.spec + " */", _HELPERS, cl_to_glsl(read_kernel("common.cl") + "\n" + cell_source())]
    head += [cl_to_glsl(src) for src in term_sources(model)]
    body = [cl_to_glsl(ln) for ln in em.lines]
    slots = "\n".join(f"    float {s.cname} = {uniform_name(s.name)};" for s in model.slots)
    value = [cl_to_glsl(" + ".join(v) if v else "0.0") for v in em.value]
    brdf = f"""vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)
{{
    float ci = dot(N, L);
    float co = dot(N, V);
    if (ci <= 0.0 || co <= 0.0)
        return vec3(0.0);
    vec3 H = normalize(L + V);
    /* the kernels' cell quantities; sin(theta_h) from a cross product keeps its precision at the peak */
    cell_t c = make_cell(length(cross(N, H)), dot(N, H), dot(L, H), ci, co);
{slots}
""" + "\n".join("    " + ln for ln in body) + f"""
    return vec3({value[0]}, {value[1]}, {value[2]});
}}"""
    return head, brdf


def brdf_explorer_text(result_json_or_doc) -> str:
    """The ``.brdf`` file of a fit result (a path to ``NAME.json`` or its parsed document)."""
    fit = load_fit(result_json_or_doc)
    model, values = fit.model, fit.values
    lines = ["analytic", "",
             f"# {fit.name}: brdfcl {model.spec}, fitted parameters as slider defaults",
             f"# generated by brdfcl {__version__} (brdfcl.report.export.brdf_explorer) "
             "from the OpenCL kernel sources",
             "# [type] [name] [min val] [max val] [default val]"]
    if model.const_names:
        terms = ", ".join(sorted({n.rsplit(".", 1)[0] for n in model.const_names}))
        lines.append(f"# the normalisation of {terms} is a constant at the fitted values: "
                     "it does not follow the sliders")
    lines += ["", "::begin parameters"]
    for s, v in zip(model.slots, values):
        lines.append(f"float {uniform_name(s.name)} {_fmt(s.param.lo)} {_fmt(s.param.hi)} {_fmt(v)}")
    lines += ["::end parameters", "", "::begin shader", shader_source(model, values).rstrip("\n"),
              "::end shader", ""]
    text = "\n".join(lines)
    bad = [ln for ln in text.split("::begin shader", 1)[1].splitlines() if ln.lstrip().startswith("#")]
    assert not bad, f"shader lines BRDF Explorer would drop as comments: {bad[:3]}"
    return text


def write_brdf_explorer(path, result_json_or_doc) -> Path:
    """Write the ``.brdf`` file of a fit result (path to ``NAME.json`` or its document) to ``path``
    (atomically); returns the path."""
    path = Path(path)
    text = brdf_explorer_text(result_json_or_doc)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
    return path
