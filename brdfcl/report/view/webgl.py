"""The live view on a material's report page: the fit drawn by WebGL 2 in the browser.

A lit sphere of the fitted model with brdfcl.report.view.sphere's conventions (orthographic, a
directional light of unit irradiance, radiance = f(wi, wo) max(0, n.wi), x right, y up, z towards
the viewer) and a polar plot of the fit in the plane of incidence (BRDF against theta_o for the
chosen theta_i, log radius, per channel; theta_o < 0 on the light's side as in the slice
figures), with sliders for the light (angle from the view, azimuth in the image), theta_i, the
exposure and every parameter (from the fitted values).  The shader is the model's GLSL from the
BRDF Explorer export in GLSL ES 3.00 (brdfcl.report.export.glsl_es) followed by
``webgl_view.glsl``; ``webgl_view.js`` runs it.  Beside it the measured table's sphere at the
nearest of the light angles drawn with the images (``turntable`` in brdfcl.report.view.material:
light at azimuth 0, turned to the slider's azimuth, exact for an isotropic table), where there is
a table.  The canvas is black off the sphere, as the sphere's unlit side; a thin ring (CSS, not
drawn in the canvas) outlines the sphere.  Everything is inline or beside the page: it works
from file:// with no server.  A browser without WebGL 2 says so in one line; the static images
stay as they are."""
from __future__ import annotations

import html
import json
import os
from functools import cache
from pathlib import Path

from brdfcl._words import count
from brdfcl.report.export.glsl_es import ES_HEADER, es_brdf_source, uniforms
from brdfcl.report.view.sphere import SRGB

FIRST_LIGHT = (45.0, 135.0)       # deg from the view, azimuth: the static key light (-0.5, 0.5, 0.71)
THETA_I = 30.0                    # the slice's incidence angle at first (deg)
CANVAS = 256                      # the sphere's canvas (pixels)
STYLE = """.brdfcl-view{display:flex;flex-wrap:wrap;gap:14px;align-items:flex-start}
.brdfcl-view figure{margin:0}.brdfcl-view canvas,.brdfcl-sphere{width:256px;height:256px;background:#000}
.brdfcl-sphere{overflow:hidden;position:relative}#brdfcl-measured{width:100%;height:100%;background-repeat:no-repeat}
.brdfcl-sphere::after{content:"";position:absolute;inset:0;border:1px solid #555;border-radius:50%;pointer-events:none}
canvas#brdfcl-slice{width:400px;height:256px;background:#fff;border:1px solid #ddd}
.brdfcl-view figcaption{max-width:256px;font-size:12px}#brdfcl-slice-text{max-width:400px}
.brdfcl-row{display:grid;grid-template-columns:11em 200px 5em;gap:6px;font-size:13px;align-items:center}
.brdfcl-controls{font-size:13px}details{margin:.4em 0}"""


@cache
def _asset(name: str) -> str:
    return (Path(__file__).parent / name).read_text(encoding="utf-8")


def fragment_shader(model, values) -> str:
    """The live view's fragment shader: GLSL ES 3.00 of the model (uniforms named as the
    parameters, `brdfcl.report.export.glsl_es`) and the view's main (``webgl_view.glsl``)."""
    srgb = "".join(f"const float SRGB_{n} = {v!r};\n" for n, v in zip(("KNEE", "SLOPE", "SCALE", "GAMMA", "OFFSET"),
                                                                      SRGB))
    return ES_HEADER + es_brdf_source(model, values) + "\n" + srgb + _asset("webgl_view.glsl")


def turntable_info(path: Path) -> dict | None:
    """What ``NAME-turntable.json`` beside the turntable PNG says (angles, step, white), or None."""
    try:
        info = json.loads(path.with_suffix(".json").read_text())
    except (OSError, ValueError):
        return None
    return info if isinstance(info, dict) and info.get("angles") else None


def config(entry, model, images, rep) -> tuple[dict, str]:
    """The view's settings (parameters as sliders, first light, exposure, measured turntable) and
    the sentence the page shows where there is no measured view ('' where there is one)."""
    slots = model.slots
    params = [{"u": u, "name": s.name, "lo": s.param.lo, "hi": s.param.hi, "log": bool(s.param.log),
               "value": float(entry.params[s.name])} for u, s in zip(uniforms(model), slots)]
    cfg = {"params": params, "light": list(FIRST_LIGHT), "theta_i": THETA_I, "white": None,
           "white_text": "", "measured": None}
    strip = (images.get("turntable") or [None])[0]
    info = turntable_info(Path(strip)) if strip else None
    if info:
        cfg["measured"] = {"src": os.path.relpath(strip, rep).replace(os.sep, "/"), "angles": info["angles"],
                           "step": info["step"], "white": info["white"]}
        cfg["white"] = info["white"]
        cfg["white_text"] = "the measured key-light sphere's 99th percentile, as the static images"
        return cfg, ""
    if entry.table is not None and not entry.tabulated:
        why = "the measurement is scattered samples, not a table"
    elif entry.table is None:
        why = "no measurement with this fit"
    else:
        why = "its images were drawn before the measured turntable existed; a fresh report draws it"
    return cfg, f"Measured view: not available ({why}); the fit alone is drawn."


def view_html(entry, images, rep) -> str:
    """The page's "Live view" section (heading, canvases, controls, shader and script)."""
    model = entry.fitted_model()
    if model.n_channels != 3:
        return (f"<h2>Live view</h2><p>The live view draws RGB fits; this fit has "
                f"{count(model.n_channels, 'channel')}.</p>")
    values = [entry.params[n] for n in model.names]
    cfg, missing = config(entry, model, images, rep)
    measured = ""
    if cfg["measured"]:
        n = len(cfg["measured"]["angles"])
        src = html.escape(cfg["measured"]["src"], quote=True).replace("'", "%27")
        measured = (f"<figure><div class='brdfcl-sphere'><div id='brdfcl-measured' style=\"background-image:"
                    f"url('{src}');background-size:{100 * n}% 100%\"></div></div>"
                    "<figcaption id='brdfcl-measured-text'></figcaption></figure>")
    slider = ("<label class='brdfcl-row'><span>{label}</span><input id='brdfcl-{key}' type='range' min='{lo}' "
              "max='{hi}' step='{step}'><output id='brdfcl-{key}-v'></output></label>")
    controls = "".join(slider.format(label=label, key=key, lo=lo, hi=hi, step=step) for label, key, lo, hi, step in (
        ("light: angle from view", "theta", 0, 180, 1), ("light: azimuth", "phi", -180, 180, 1),
        ("slice: \u03b8i", "ti", 0, 89, 1), ("exposure (stops, fit)", "stops", -8, 8, 0.1)))
    data = json.dumps(cfg, separators=(",", ":")).replace("</", "<\\/")
    consts = ""
    if model.const_names:
        terms = ", ".join(sorted({n.rsplit(".", 1)[0] for n in model.const_names}))
        consts = f"; the normalisation of {html.escape(terms)} stays at the fitted values"
    return "\n".join([
        f"<h2 id='live-view'>Live view</h2><style>{STYLE}</style>",
        "<p id='brdfcl-view-note'>" + html.escape(missing) + "</p>",
        "<div id='brdfcl-view'><div class='brdfcl-view'>",
        f"<figure><div class='brdfcl-sphere'><canvas id='brdfcl-fit' width='{CANVAS}' height='{CANVAS}'></canvas></div>"
        "<figcaption id='brdfcl-fit-text'></figcaption></figure>",
        measured,
        "<figure><canvas id='brdfcl-slice' width='400' height='256'></canvas>"
        "<figcaption id='brdfcl-slice-text'></figcaption></figure></div>",
        f"<div class='brdfcl-controls'>{controls}<details><summary>model parameters (from the fit; "
        f"they change this view only{consts}) <button id='brdfcl-reset' type='button'>reset</button></summary>"
        "<div id='brdfcl-params'></div></details></div></div>",
        f"<script type='application/json' id='brdfcl-view-config'>{data}</script>",
        f"<script type='x-shader/x-fragment' id='brdfcl-fs'>{fragment_shader(model, values)}</script>",
        f"<script>{_asset('webgl_view.js')}</script>"])
