"""A fitted model's BRDF in GLSL ES 3.00 (WebGL 2), from the GLSL the BRDF Explorer export generates.

    from brdfcl.report.export.glsl_es import es_brdf_source
    src = es_brdf_source(model, values)     # uniforms, helpers, vec3 BRDF(L, V, N, X, Y)

The BRDF is `brdfcl.report.export.brdf_explorer.shader_source`: the OpenCL kernel sources
translated to GLSL 4.10, so that a browser draws the same formulas the fit evaluated (nothing
is written by hand).  That translation uses only what GLSL ES 3.00 has too (``float``, ``vec3``,
structs, ``out`` parameters, ``?:``, the common builtins), so going to ES is: the version line,
precision qualifiers (``highp``: the BRDF is float32 as on the fitting device) and a ``uniform
float`` per parameter, named as BRDF Explorer's sliders are (`uniform_name`: ``ct.alpha`` ->
``ct_alpha``).  A construct of desktop GLSL that ES lacks is refused (ValueError) rather than
left to a browser's compiler.  Host constants (the SGD and EPD normalisations) stay constants at
the fitted values, as in the export.
"""
from __future__ import annotations

import re
from functools import lru_cache

from brdfcl.model.compose import Model
from brdfcl.report.export.brdf_explorer import shader_source, uniform_name

ES_VERSION = "#version 300 es"
ES_HEADER = ES_VERSION + "\nprecision highp float;\nprecision highp int;\n"

_DESKTOP_ONLY = re.compile(r"\b(double|dvec[234]|dmat\w*|fma|subroutine|precise|noperspective|"
                           r"packDouble2x32|unpackDouble2x32|texture[123]D|gl_FragData)\b|#\s*extension")


def uniforms(model: Model) -> list[str]:
    """The uniform of each of the model's parameters, in the model's order."""
    return [uniform_name(s.name) for s in model.slots]


def to_glsl_es(src: str, names) -> str:
    """GLSL 4.10 of `shader_source` -> the body of a GLSL ES 3.00 shader (``ES_HEADER`` comes
    first, then this): one ``uniform float`` per name in ``names``, then ``src``."""
    code = re.sub(r"/\*.*?\*/|//[^\n]*", "", src, flags=re.S)
    left = sorted({m.group(0) for m in _DESKTOP_ONLY.finditer(code)})
    if left:
        raise ValueError(f"GLSL 4.10 constructs that GLSL ES 3.00 lacks: {left}")
    decl = "".join(f"uniform float {n};\n" for n in names)
    return "/* the model's parameters (brdfcl.report.export.glsl_es) */\n" + decl + "\n" + src


@lru_cache(maxsize=64)
def _cached(spec: str, lambdas: tuple, values: tuple | None) -> str:
    model = Model(spec, lambdas=lambdas)
    return to_glsl_es(shader_source(model, model.defaults() if values is None else values), uniforms(model))


def es_brdf_source(model: Model, values) -> str:
    """The GLSL ES 3.00 BRDF of ``model`` (after ``ES_HEADER``): a uniform per parameter and
    ``vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)``.  ``values`` matter only where the model
    has host constants (written at these values); otherwise the translation is made once per model."""
    key = tuple(float(v) for v in values) if model.const_names else None
    return _cached(model.spec, tuple(model.lambdas), key)
