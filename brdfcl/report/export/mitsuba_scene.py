"""A fit as Mitsuba 3 scene files: the ``"brdfcl"`` BSDF, and Mitsuba's own BSDFs where they match.

    from brdfcl.report.export.mitsuba_scene import write_mitsuba
    write_mitsuba("mitsuba/", "fits/brass.json")     # or the parsed NAME.json document

writes into the folder (nothing here needs Mitsuba installed):

* ``NAME.json``, the fit, and ``NAME.xml``, a scene fragment that declares the BSDF
  ``<bsdf type="brdfcl" id="NAME">`` reading it (include it with ``<include filename="NAME.xml"/>``
  and use it with ``<ref id="NAME"/>``; its paths are relative to the folder, which Mitsuba
  searches when it loads a scene file there: a scene elsewhere adds the folder to
  ``mi.file_resolver()`` first);
* ``NAME-builtin.xml`` (id ``NAME-builtin``), where the fit maps onto Mitsuba's own BSDFs, which
  render it with no brdfcl installed;
* ``NAME-scene.xml`` (and ``NAME-builtin-scene.xml``): a complete scene, a unit sphere under a key
  light and a dim sky, seen by a 256 x 256 camera, ready for ``mi.load_file``;
* ``NAME.py``: the same as Python dicts for ``mi.load_dict`` (``BSDF``, ``BUILTIN`` or None, and
  ``BUILTIN_NOTE``, which says how closely the built-in BSDFs match the fit).

The built-in mapping.  Mitsuba has no sum of BSDFs; a ``blendbsdf`` of weight w with the parts
divided by their weights is one: (1 - w) f_d / (1 - w) + w f_s / w, w = max rho_s / (max rho_s +
max rho_d) where the two add up to at most 1, else 1 - max rho_d.  Mitsuba refuses an ``rgb``
reflectance above 1 (a fit's rho_s may be, where its Fresnel reflects less than the
material); such a reflectance is written as a 1 x 1 EXR (``NAME-reflectance.exr``,
``NAME-specular_reflectance.exr``) read by a ``bitmap`` texture, which Mitsuba takes with a
warning.  The diffuse lobe is ``diffuse`` (rho / pi, as brdfcl's).  A GGX Cook-Torrance lobe
with separable Smith shadowing is ``roughconductor`` (``distribution="ggx"``, the same alpha;
Mitsuba's D, G1 and F are the formulas brdfcl's terms are, rho as ``specular_reflectance``),
exactly, with its Fresnel as:

* ``conductor``: ``eta``, ``k`` per channel;
* ``dielectric``: ``eta`` with ``k = 0`` (the conductor formula with k = 0 is the dielectric one);
* ``none``: ``material="none"`` (F = 1).

Approximate mappings, each stated with the largest relative difference of the BRDF over
directions up to 80 degrees from the normal (measured on a fixed grid by brdfcl's float64
reference when the file is written): Schlick's Fresnel as a ``k = 0`` conductor of the same
reflectance at normal incidence (eta = (1 + sqrt F0) / (1 - sqrt F0) per channel); height-correlated
Smith as Mitsuba's separable one; a Beckmann lobe (Mitsuba's Beckmann G1 is Walter's rational
approximation of brdfcl's erfc form).  Any other lobe (a diffraction lobe, GTR, ABC, SGD, EPD,
V-cavity or no shadowing, two reflection lobes) has no built-in counterpart: ``NAME-builtin.xml``
is not written and the note says why.
"""
from __future__ import annotations

import json
import pprint
import re
from pathlib import Path
from typing import Any

import numpy as np

from brdfcl._words import count
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.report.export.fitfile import load_fit
from brdfcl.report.files import atomic_write_text

KEY_LIGHT = (-0.5, 0.5, 0.7071)
"""Direction towards the key light of the example scene (brdfcl's report spheres use the same)."""
_CHECK_DEG = 80.0
"""The stated differences are over directions up to this angle from the normal."""


class Mapping:
    """Mitsuba's own BSDFs for a fit: ``bsdf`` (a dict for ``mi.load_dict``, None when there is
    none), ``exact`` and ``note`` (in words; for an approximate one, the largest difference)."""

    def __init__(self, bsdf: dict | None, exact: bool, note: str):
        self.bsdf, self.exact, self.note = bsdf, exact, note


def _rgb(x) -> dict:
    return {"type": "rgb", "value": [float(v) for v in x]}


def builtin_mapping(model: Model, values) -> Mapping:
    """Mitsuba's BSDFs that render ``model`` at ``values`` (see the module's docstring)."""
    values = np.asarray(values, dtype=np.float64)
    v = model.as_dict(values)
    lobes: dict[str, list[Any]] = {lb.role: [x for x in model.lobes if x.role == lb.role] for lb in model.lobes}
    why = []
    if model.n_channels != 3:
        return Mapping(None, False, f"no Mitsuba built-in BSDF for a fit of {count(model.n_channels, 'channel')} "
                                    f"(Mitsuba's RGB BSDFs need 3)")
    if lobes.get("diffraction"):
        why.append("a diffraction lobe")
    if len(lobes.get("diffuse", [])) > 1 or len(lobes.get("reflection", [])) > 1:
        why.append("two lobes of one kind")
    ct = (lobes.get("reflection") or [None])[0]
    if ct is not None:
        if ct.ndf.name not in ("ggx", "beckmann"):
            why.append(f"the {ct.ndf.name} distribution")
        if ct.shadowing.family not in ("smith", "smith-hc"):
            why.append(f"{ct.shadowing.family} shadowing")
    if why:
        return Mapping(None, False, f"no Mitsuba built-in BSDF for {' and '.join(why)} ({model.spec})")
    parts: list[dict[str, Any]] = []
    approx: list[str] = []
    if lobes.get("diffuse"):
        d = lobes["diffuse"][0]
        parts.append({"type": "diffuse",
                      "reflectance": _rgb([v[d.slot_name("rho", c)] for c in range(3)])})
    if ct is not None:
        n = range(3)
        spec: dict[str, Any] = {"type": "roughconductor", "distribution": ct.ndf.name,
                                "alpha": float(v[ct.slot_name("alpha")]),
                                "specular_reflectance": _rgb([v[ct.slot_name("rho", c)] for c in n])}
        fr = ct.fresnel.name
        if fr == "conductor":
            spec["eta"] = _rgb([v[ct.slot_name("eta", c)] for c in n])
            spec["k"] = _rgb([v[ct.slot_name("k", c)] for c in n])
        elif fr == "dielectric":
            spec["eta"] = _rgb([v[ct.slot_name("eta")]] * 3)
            spec["k"] = _rgb([0.0] * 3)
        elif fr == "none":
            spec["material"] = "none"
        else:                                       # schlick: the conductor of the same F0, k = 0
            f0 = np.sqrt(np.clip([v[ct.slot_name("F0", c)] for c in n], 0.0, 0.999))
            spec["eta"] = _rgb((1 + f0) / (1 - f0))
            spec["k"] = _rgb([0.0] * 3)
            approx.append("Schlick's Fresnel as a conductor of the same F0 (k = 0)")
        if ct.shadowing.family == "smith-hc":
            approx.append("height-correlated Smith as separable")
        if ct.ndf.name == "beckmann":
            approx.append("Beckmann's Smith G1 as Walter's rational approximation")
        parts.append(spec)
    if len(parts) == 2:
        md = max(parts[0]["reflectance"]["value"])
        ms = max(parts[1]["specular_reflectance"]["value"])
        if md <= 0 or ms <= 0:                   # a part that reflects nothing is left out
            parts = [parts[1] if md <= 0 else parts[0]]
    if len(parts) == 2:
        # f_d + f_s as (1 - w) (f_d / (1 - w)) + w (f_s / w): w splits the amplitudes so that both
        # stay at most 1 where they can, else keeps the diffuse part at most 1
        w = ms / (ms + md) if ms + md <= 1 or md >= 1 else 1 - md
        parts[0]["reflectance"] = _rgb([x / (1 - w) for x in parts[0]["reflectance"]["value"]])
        parts[1]["specular_reflectance"] = _rgb([x / w for x in parts[1]["specular_reflectance"]["value"]])
        bsdf = {"type": "blendbsdf", "weight": w, "bsdf_0": parts[0], "bsdf_1": parts[1]}
    else:
        bsdf = parts[0]
    if not approx:
        return Mapping(bsdf, True, f"exact: Mitsuba's {_names(bsdf)} are this fit's formulas")
    diff = _difference(model, values, bsdf)
    return Mapping(bsdf, False, f"approximate ({'; '.join(approx)}): the BRDF differs by up to "
                                f"{100 * diff:.2g}% (directions to {_CHECK_DEG:g} deg)")


def _names(bsdf: dict) -> str:
    if bsdf["type"] == "blendbsdf":
        return f"diffuse and roughconductor ({bsdf['bsdf_1']['distribution']})"
    return f"{bsdf['type']}" + (f" ({bsdf['distribution']})" if "distribution" in bsdf else "")


def _directions():
    t = np.radians(np.linspace(0.0, _CHECK_DEG, 17))
    p = np.radians(np.linspace(0.0, 180.0, 13))
    ti, to, po = (a.ravel() for a in np.meshgrid(t, t, p, indexing="ij"))
    wi = np.stack([np.sin(ti), np.zeros_like(ti), np.cos(ti)], -1)
    wo = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)], -1)
    keep = np.linalg.norm(wi + wo, axis=-1) > 1e-6
    return wi[keep], wo[keep]


def _builtin_reference(bsdf: dict, cells: Any) -> np.ndarray:
    """Mitsuba's diffuse + roughconductor, as Mitsuba writes them, in float64: (3, n)."""
    from brdfcl.model.terms import REGISTRY
    if bsdf["type"] == "blendbsdf":
        w = bsdf["weight"]
        parts = [(1 - w, bsdf["bsdf_0"]), (w, bsdf["bsdf_1"])]
    else:
        parts = [(1.0, bsdf)]
    out = np.zeros((3, len(cells)))
    for scale, p in parts:
        if p["type"] == "diffuse":
            out += scale * np.array(p["reflectance"]["value"])[:, None] / np.pi
            continue
        a = p["alpha"]
        D = REGISTRY["ndf"][p["distribution"]].reference(cells, alpha=a)[0]
        if p["distribution"] == "ggx":
            G = REGISTRY["shadowing"]["smith_ggx"].reference(cells, alpha=a)[0]
        else:
            G = _walter_g1(a, cells.t2i) * _walter_g1(a, cells.t2o)
        rho = np.array(p["specular_reflectance"]["value"])
        for c in range(3):
            if p.get("material") == "none":
                F = 1.0
            else:
                F = REGISTRY["fresnel"]["conductor"].reference(
                    cells, eta=p["eta"]["value"][c], k=p["k"]["value"][c])[0]
            out[c] += scale * rho[c] * D * G * F * cells.inv4cico
    return out


def _walter_g1(alpha, t2):
    """Mitsuba's Beckmann Smith G1: Walter et al. 2007's rational fit (eq. 27) of the erfc form."""
    a = 1.0 / (alpha * np.sqrt(np.maximum(t2, 1e-300)))
    return np.where(a >= 1.6, 1.0, (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a))


def _difference(model: Model, values, bsdf: dict) -> float:
    wi, wo = _directions()
    cells = Cells.from_directions(wi, wo)
    f = model.reference(cells, values, jacobian=False)
    g = _builtin_reference(bsdf, cells)
    ok = f > 1e-12 * f.max()
    return float(np.max(np.abs(g[ok] - f[ok]) / f[ok]))


# --- writing ------------------------------------------------------------------------------------

_REFLECTANCES = ("reflectance", "specular_reflectance")


def _with_textures(bsdf: dict, name: str) -> tuple[dict, dict]:
    """The BSDF as written: each reflectance above 1 as a ``bitmap`` of a 1 x 1 EXR named after it;
    and {EXR file name: its RGB}."""
    files: dict = {}

    def walk(obj):
        out = {}
        for k, v in obj.items():
            if isinstance(v, dict) and v.get("type") == "rgb" and k in _REFLECTANCES and max(v["value"]) > 1:
                fname = f"{name}-{k}.exr"
                files[fname] = v["value"]
                out[k] = {"type": "bitmap", "filename": fname, "raw": True, "filter_type": "nearest"}
            elif isinstance(v, dict):
                out[k] = walk(v)
            else:
                out[k] = v
        return out
    return walk(bsdf), files


def _quoteattr(text: str) -> str:
    """``text`` as a quoted XML attribute value."""
    from xml.sax.saxutils import quoteattr  # here: it imports urllib, 50 ms of every start-up
    return quoteattr(text)


def _xml_value(name: str, value, indent: str) -> list[str]:
    if isinstance(value, dict) and value.get("type") == "rgb":
        return [f'{indent}<rgb name="{name}" value="{", ".join(f"{x:.9g}" for x in value["value"])}"/>']
    if isinstance(value, dict):
        tag = "texture" if value["type"] == "bitmap" else "bsdf"
        return _xml_object(tag, value, indent, name=name if tag == "texture" else None)
    if isinstance(value, bool):
        return [f'{indent}<boolean name="{name}" value="{str(value).lower()}"/>']
    if isinstance(value, str):
        return [f'{indent}<string name="{name}" value={_quoteattr(value)}/>']
    return [f'{indent}<float name="{name}" value="{float(value):.9g}"/>']


def _xml_object(tag: str, obj: dict, indent: str, name: str | None = None, id: str | None = None) -> list[str]:
    attrs = f' type="{obj["type"]}"' + (f" id={_quoteattr(id)}" if id else "") + (f' name="{name}"' if name else "")
    lines = [f"{indent}<{tag}{attrs}>"]
    for k, v in obj.items():
        if k != "type":
            lines += _xml_value(k, v, indent + "    ")
    return lines + [f"{indent}</{tag}>"]


def _fragment(bsdf: dict, id: str, comment: str) -> str:
    lines = ['<scene version="3.0.0">', f"    <!-- {comment} -->"]
    return "\n".join(lines + _xml_object("bsdf", bsdf, "    ", id=id) + ["</scene>"]) + "\n"


def _scene_xml(fragment: str, id: str, needs_brdfcl: bool) -> str:
    x, y, z = np.array(KEY_LIGHT) / np.linalg.norm(KEY_LIGHT)
    note = ('    <!-- needs the "brdfcl" plugin: import brdfcl.report.export.mitsuba before loading -->\n'
            if needs_brdfcl else "    <!-- Mitsuba's own plugins only -->\n")
    return f"""<scene version="3.0.0">
{note}    <include filename="{fragment}"/>
    <default name="spp" value="64"/>
    <default name="res" value="256"/>
    <integrator type="path">
        <integer name="max_depth" value="3"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="28"/>
        <transform name="to_world">
            <lookat origin="0, 0, 4.5" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="$res"/>
            <integer name="height" value="$res"/>
            <rfilter type="box"/>
            <string name="pixel_format" value="rgb"/>
        </film>
    </sensor>
    <shape type="sphere">
        <ref id="{id}"/>
    </shape>
    <emitter type="directional">
        <vector name="direction" value="{-x:.6g}, {-y:.6g}, {-z:.6g}"/>
        <rgb name="irradiance" value="3, 3, 3"/>
    </emitter>
    <emitter type="constant">
        <rgb name="radiance" value="0.05, 0.05, 0.05"/>
    </emitter>
</scene>
"""


def _python(name: str, fit_file: str, builtin: dict | None, note: str) -> str:
    here = "os.path.dirname(os.path.abspath(__file__))"

    def text(obj):
        out = pprint.pformat(obj, sort_dicts=False, width=100)
        for fname in [fit_file, *(f"{name}-{k}.exr" for k in _REFLECTANCES)]:
            out = out.replace(repr(fname), f"os.path.join(HERE, {fname!r})")
        return out
    return (f'"""Mitsuba 3 dicts of the brdfcl fit {name!r} (mi.load_dict).\n\n'
            f'BSDF needs the "brdfcl" plugin (import brdfcl.report.export.mitsuba); BUILTIN, where it is\n'
            f'not None, is Mitsuba\'s own BSDFs.  BUILTIN_NOTE says how closely those match the fit."""\n'
            f"import os\n\nHERE = {here}\n\nBSDF = {text({'type': 'brdfcl', 'fit': fit_file})}\n\n"
            f"BUILTIN = {text(builtin) if builtin else 'None'}\n\n"
            f"BUILTIN_NOTE = {note!r}\n")


def write_mitsuba(out_dir, src) -> tuple[list[Path], Mapping]:
    """Write the Mitsuba files of one fit (a ``NAME.json`` path or its document) into ``out_dir``;
    the files written, in order, and the built-in mapping.  ValueError (one line) for a fit the
    BSDF cannot render or a folder holding another fit of the same name."""
    from brdfcl.report.files import write_exr
    fit = load_fit(src)
    if fit.model.n_channels != 3:
        raise ValueError(f"{fit.name}: a fit of {count(fit.model.n_channels, 'channel')}; Mitsuba's RGB variants "
                         f"render fits of 3 (R, G, B): fit with --rgb")
    out = Path(out_dir)
    name = re.sub(r"[^A-Za-z0-9._+-]", "_", fit.name)
    fit_file = f"{name}.json"
    target = out / fit_file
    if target.exists():
        try:
            same = json.loads(target.read_text(encoding="utf-8")) == fit.doc
        except (OSError, ValueError):
            same = False
        if not same:
            raise ValueError(f"{target}: holds another fit; write the Mitsuba files into another folder")
    out.mkdir(parents=True, exist_ok=True)
    mapping = builtin_mapping(fit.model, fit.values)
    written = []

    def put(fname, text):
        p = out / fname
        atomic_write_text(p, text)
        written.append(p)
    if not target.exists():
        put(fit_file, json.dumps(fit.doc, indent=1) + "\n")
    put(f"{name}.xml", _fragment({"type": "brdfcl", "fit": fit_file}, name,
                                 f"brdfcl fit {fit.name} ({fit.model.spec}); "
                                 f"the plugin: import brdfcl.report.export.mitsuba"))
    put(f"{name}-scene.xml", _scene_xml(f"{name}.xml", name, True))
    builtin = None
    if mapping.bsdf is not None:
        builtin, textures = _with_textures(mapping.bsdf, name)
        for fname, rgb in textures.items():
            write_exr(out / fname, {c: np.full((1, 1), v, dtype=np.float32) for c, v in zip("RGB", rgb)})
            written.append(out / fname)
        put(f"{name}-builtin.xml", _fragment(builtin, f"{name}-builtin", f"{fit.name} with Mitsuba's own BSDFs: "
                                             + mapping.note.replace("--", "-")))
        put(f"{name}-builtin-scene.xml", _scene_xml(f"{name}-builtin.xml", f"{name}-builtin", False))
    put(f"{name}.py", _python(name, fit_file, builtin, mapping.note))
    return written, mapping
