"""Lit spheres of a fitted model and of a measured MERL table, with brdfcl's own code.

Camera: orthographic, looking along -z at a unit sphere that exactly fills a ``size`` x ``size``
frame (pixel centres; x right, y up, row 0 at the top); NaN outside the sphere.  Normal
n = (x, y, sqrt(1 - x^2 - y^2)), view direction (0, 0, 1).  A point light is a directional light
of unit irradiance from ``light_dir``: radiance = f(wi, wo) max(0, n.wi).  The environment is a
sky/ground gradient whose zenith is ``light_dir``; it is integrated per pixel with one fixed set
of half vectors in the pixel's local frame, spaced logarithmically near the normal, so that lobes
as sharp as alpha ~ 1e-3 are integrated as well as broad ones (a fixed set of light directions
would show a sharp lobe as dots).  The BRDF is evaluated in each pixel's local frame (tangent
from Duff et al.'s basis; brdfcl's lobes are isotropic), the model with its float64 reference,
the table by trilinear lookup (of log values) in MERL's (theta_h, theta_d, phi_d) index space
(brdfcl.report.view.lookup, which the slice plots use too): the exact renderings
(``render_model_sphere``, ``render_table_sphere``).  The report takes the same pixels' values
from its plan (brdfcl.report.view.views) and writes them with ``write_sphere_images``: PNG panels
(Pillow) whose captions go to the page, and EXR layers.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from brdfcl.data.merl import MerlTable
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.report import files
from brdfcl.report.files import write_exr
from brdfcl.report.view.lookup import table_lookup

CHUNK = 1 << 18                   # (pixel, sample) pairs evaluated at once
SKY_ZENITH = np.array([0.35, 0.55, 1.0])
SKY_HORIZON = np.array([1.0, 0.97, 0.9])
GROUND = np.array([0.25, 0.22, 0.2])
THUMB_SIZE = 96                   # the thumbnail's spheres (pixels)
ENV_SIZE = 96                     # environment spheres at most this size (600 BRDF values a pixel)
MIN_VALID_SHARE = 0.95            # table sphere in the environment: NaN below this share of light


def _unit(*v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


# The light of each view: a direction (point light) or the environment's zenith.
# Angles from the view: key 45, side 110, grazing 150 deg (its highlight at theta_i = theta_o = 75).
DEFAULT_LIGHTS = (("key", "point", _unit(-0.5, 0.5, 0.7071)),        # from the upper left
                  ("front", "point", _unit(0.0, 0.0, 1.0)),            # from the camera
                  ("side", "point", _unit(0.94, 0.0, -0.342)),         # from the right, behind
                  ("grazing", "point", _unit(0.0, 0.5, -0.866)),       # from above, behind: rim
                  ("env", "env", _unit(0.0, 1.0, 0.0)))                # sky above, ground below


def as_model(model, values):
    """(Model, value vector) from a Model or spec string and a vector or {name: value}."""
    model = Model(model) if isinstance(model, str) else model
    if isinstance(values, dict):
        values = [values[n] for n in model.names]
    return model, np.asarray(values, dtype=np.float64)


# --- rendering ---------------------------------------------------------------------------------
def sphere_normals(size):
    """Normals (size, size, 3) at the pixel centres and the mask of pixels on the sphere."""
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    x, y = np.meshgrid(c, -c)
    r2 = x * x + y * y
    inside = r2 < 1.0
    return np.stack([x, y, np.sqrt(np.maximum(1.0 - r2, 0.0))], -1), inside


def local_frame(n):
    """Tangent and bitangent (n, 3) of unit normals with n_z > -1 (Duff et al. 2017)."""
    a = -1.0 / (1.0 + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + n[:, 0] ** 2 * a, b, -n[:, 0]], -1)
    return t, np.stack([b, 1.0 + n[:, 1] ** 2 * a, -n[:, 1]], -1)


def environment(w, zenith):
    """Radiance (..., 3) of the sky/ground gradient in directions w (..., 3)."""
    c = (w @ zenith)[..., None]
    sky = SKY_HORIZON + (SKY_ZENITH - SKY_HORIZON) * np.sqrt(np.clip(c, 0.0, 1.0))
    return np.where(c > 0, sky, GROUND)


def half_vector_samples(n_log=40, n_lin=16, m_log=6, m_lin=24, theta_min=1e-5, theta_split=0.15):
    """Local half vectors (k, 3) and their solid angles (k,): rings of theta_h spaced
    logarithmically from theta_min to theta_split (sharp peaks), evenly above (broad lobes)."""
    edges = np.concatenate([[0.0], np.geomspace(theta_min, theta_split, n_log),
                            np.linspace(theta_split, np.pi / 2, n_lin + 1)[1:]])
    h, w = [], []
    for k, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        m = m_log if k < n_log else m_lin
        t = np.sqrt(a * b) if a > 0 and k < n_log else 0.5 * (a + b)
        phi = 2 * np.pi * (np.arange(m) + (k * 0.618034) % 1.0) / m
        h.append(np.stack([np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.full(m, np.cos(t))], -1))
        w.append(np.full(m, 2 * np.pi * (np.cos(a) - np.cos(b)) / m))
    return np.concatenate(h), np.concatenate(w)


def pixel_frames(size):
    """The sphere's pixels: the mask (size, size) of those on it and, for each of them, the normal
    n, tangent t, bitangent b (m, 3) and the view direction in its local frame, wo (m, 3)."""
    normals, inside = sphere_normals(size)
    n = normals[inside]
    t, b = local_frame(n)
    return inside, n, t, b, np.stack([t[:, 2], b[:, 2], n[:, 2]], -1)   # (0, 0, 1) in each frame


def point_samples(n, t, b, light_dir):
    """The pixels a point light from ``light_dir`` reaches: their indices, cos(theta_i) and the
    light's direction in their local frames."""
    cos = n @ light_dir
    lit = np.flatnonzero(cos > 0)
    return lit, cos[lit], np.stack([t[lit] @ light_dir, b[lit] @ light_dir, cos[lit]], -1)


def env_samples(n, t, b, wo, zenith):
    """The environment's samples of these pixels (half_vector_samples reflected about the view):
    for each, its pixel's index, wi in the pixel's local frame and its weight (m, 3), the
    solid-angle measure 4 (h.wo) cos(theta_i) d(omega_h) times the environment's radiance."""
    hs, dw = half_vector_samples()
    hw = wo @ hs.T                                                     # (P, K): h.wo = h.wi
    wi = 2.0 * hw[..., None] * hs - wo[:, None, :]
    pix, k = np.nonzero((hw > 0) & (wi[..., 2] > 0))
    wi, hw = wi[pix, k], hw[pix, k]
    world = wi[:, :1] * t[pix] + wi[:, 1:2] * b[pix] + wi[:, 2:] * n[pix]
    return pix, wi, (4.0 * hw * wi[:, 2] * dw[k])[:, None] * environment(world, zenith)


def render_sphere(brdf, light_dir, size=128, light="point"):
    """Radiance (size, size, 3) of the sphere for ``brdf(wi, wo) -> (3, n)`` (local frame, n = z)."""
    light_dir = _unit(*light_dir)
    inside, n, t, b, wo = pixel_frames(size)
    out = np.full((size, size, 3), np.nan)
    if light == "point":
        rad = np.zeros((n.shape[0], 3))
        lit, cos, wi = point_samples(n, t, b, light_dir)
        rad[lit] = (brdf(wi, wo[lit]) * cos).T
    elif light == "env":
        rad = _integrate_env(brdf, n, t, b, wo, light_dir)
    else:
        raise ValueError(f"light '{light}': point or env")
    out[inside] = rad
    return out


def _integrate_env(brdf, n, t, b, wo, zenith):
    rad = np.zeros((n.shape[0], 3))
    step = max(1, CHUNK // half_vector_samples()[0].shape[0])
    for s in range(0, n.shape[0], step):
        p = slice(s, s + step)
        pix, wi, weight = env_samples(n[p], t[p], b[p], wo[p], zenith)
        f = brdf(wi, wo[p][pix]).T
        good = np.isfinite(f)
        m = wo[p].shape[0]
        total, share, r = (np.stack([np.bincount(pix, x[:, c], minlength=m) for c in range(3)], -1)
                           for x in (weight, np.where(good, weight, 0.0), np.where(good, f * weight, 0.0)))
        share = share / np.maximum(total, 1e-300)
        rad[p] = np.where(share >= MIN_VALID_SHARE, r / np.maximum(share, 1e-300), np.nan)
    return rad


def render_model_sphere(model, values, light_dir, size=128, light="point"):
    """Linear radiance (size, size, 3) of a model (Model or spec) with ``values`` (vector or
    {name: value}): its float64 reference in each pixel's local frame; NaN outside the sphere."""
    model, values = as_model(model, values)
    return render_sphere(lambda wi, wo: model.reference(Cells.from_directions(wi, wo), values,
                                                        jacobian=False), light_dir, size, light)


def render_table_sphere(table, light_dir, size=128, light="point", interp="log"):
    """Linear radiance (size, size, 3) of a MerlTable (or (3, N_CELLS) BRDF array) looked up
    per pixel (``table_lookup``); NaN outside the sphere and where the table is missing."""
    brdf = table.brdf() if isinstance(table, MerlTable) else np.asarray(table)
    brdf = np.ascontiguousarray(brdf.T).T                              # cells-major: fast lookups
    return render_sphere(lambda wi, wo: table_lookup(brdf, wi, wo, interp), light_dir, size, light)


# --- images ------------------------------------------------------------------------------------
def exposure(img):
    """Scale that maps the 99th percentile of the lit pixels' brightest channel to 1."""
    f = np.where(np.isfinite(img), img, -np.inf)
    m = np.maximum.reduce([f[..., c] for c in range(f.shape[-1])])      # not max(-1): slow over 3 values
    lit = m[m > 0]
    return 1.0 / np.percentile(lit, 99) if lit.size else 1.0


SRGB = (0.0031308, 12.92, 1.055, 2.4, 0.055)
"""The sRGB transfer function (IEC 61966-2-1): slope x below the knee, scale x^(1/gamma) - offset
above; the report's images and its live view (webgl_view.glsl) encode with it."""


def to_srgb(img, scale, background=0.18):
    """Display image (uint8): ``img * scale`` clipped to [0, 1], sRGB transfer function; outside
    the sphere (NaN in every channel) ``background`` (a display value), missing measurements
    magenta."""
    x = np.multiply(img, scale * _LUT_MAX)
    np.fmax(x, 0.0, out=x)                                # fmax, fmin: NaN to 0
    np.fmin(x, _LUT_MAX, out=x)
    out = np.take(_srgb_codes(), np.rint(x, out=x).astype(np.int32))
    nan = np.isnan(img)
    channels = [nan[..., c] for c in range(img.shape[-1])]   # not any(-1): slow over 3 values
    out[np.logical_or.reduce(channels)] = (255, 0, 255)
    out[np.logical_and.reduce(channels)] = int(background * 255.0 + 0.5)
    return out


_LUT_MAX = 65535                  # linear steps of the transfer function's table: far finer than 8-bit codes


@lru_cache(maxsize=1)
def _srgb_codes() -> np.ndarray:
    """The sRGB transfer function as 8-bit codes at ``_LUT_MAX + 1`` linear steps over [0, 1]."""
    return _code(np.linspace(0.0, 1.0, _LUT_MAX + 1))


def _code(x):
    """8-bit sRGB codes of linear values in [0, 1] (`SRGB`)."""
    knee, slope, scale, gamma, offset = SRGB
    x = np.asarray(x, dtype=np.float64)
    return (np.where(x <= knee, slope * x, scale * x ** (1 / gamma) - offset) * 255.0 + 0.5).astype(np.uint8)


def panels(images, scale, gap=4, background=0.18):
    """sRGB uint8 image of ``images`` (each (n, n, 3), linear) side by side at one exposure."""
    return side_by_side([to_srgb(img, scale, background) for img in images], gap)


def side_by_side(srgb, gap=4):
    """uint8 images of one height side by side, ``gap`` white columns apart."""
    strip = np.full((srgb[0].shape[0], gap, 3), 255, dtype=np.uint8)
    out = [srgb[0]]
    for img in srgb[1:]:
        out += [strip, img] if gap else [img]
    return np.concatenate(out, axis=1)


def exposed(images) -> dict:
    """{label: (exposure, sRGB image)} of measured sphere images ({label: radiance}): how their
    panels show them (`exposure`, `to_srgb`), made once for the fitted side's panels."""
    out = {}
    for label, img in images.items():
        scale = exposure(img)
        out[label] = (scale, to_srgb(img, scale))
    return out


def write_png(path, rgb, size=None):
    """Write a uint8 RGB image (h, w, 3) as PNG (brdfcl.report.files.write_png), resampled to
    ``size`` (w, h) where given (a box filter), atomically (a failed write: one line naming the path)."""
    if size is not None and tuple(size) != (rgb.shape[1], rgb.shape[0]):
        from PIL import Image
        rgb = np.asarray(Image.fromarray(rgb).resize(size, Image.Resampling.BOX))
    files.write_png(path, rgb)


def light_text(kind, d):
    """What lights the sphere, in words."""
    xyz = "({:.2f}, {:.2f}, {:.2f})".format(*d)
    if kind == "env":
        return f"sky/ground environment, zenith {xyz}"
    return f"point light from {xyz}, {np.degrees(np.arccos(np.clip(d[2], -1, 1))):.0f} deg from the view"


def sphere_caption(kind, d, meas, fit, spec, scale):
    """The caption of a sphere image: what lights it, the exposure and the median difference."""
    ok = np.isfinite(meas) & (meas > 0) & np.isfinite(fit)
    rel = np.median(np.abs(fit[ok] - meas[ok]) / meas[ok]) if ok.any() else np.nan
    unit = "x the sky's horizon" if kind == "env" else "/sr x unit irradiance"
    return (f"measured (table) | fitted: {spec} | |fitted - measured| at the same exposure "
            f"(median relative difference {100 * rel:.3g} %). {light_text(kind, d)}; camera: x right, y up, "
            f"z towards the viewer; white = {1 / scale:.3g} {unit} (99th percentile of measured), sRGB; "
            "magenta: missing.")


def write_sphere_images(out_dir, name, spec, lights, measured, fitted, shown=None):
    """Per light, ``NAME-sphere-LIGHT.png`` (measured | fitted | |difference|, one exposure from
    the measured image, sRGB) and ``NAME-sphere-LIGHT.exr`` (linear float32; layers measured.R/G/B,
    fitted.*: -1 outside the sphere and where missing; difference.* = fitted - measured, 0 there;
    A: 1 on the sphere); and ``NAME-thumb.png``, measured | fitted under the first light at
    THUMB_SIZE.  ``measured`` and ``fitted``: {label: radiance image}; ``shown``: `exposed` of
    the measured images, where made before.  Returns (paths, {png name: caption})."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    shown = shown if shown is not None else exposed({label: measured[label] for label, _, _ in lights})
    paths, captions, thumb = [], {}, None
    for label, kind, d in lights:
        meas, fit = measured[label], fitted[label]
        scale, meas_srgb = shown[label]
        fit_srgb = to_srgb(fit, scale)
        thumb = thumb if thumb is not None else side_by_side([meas_srgb, fit_srgb], gap=0)
        png = out_dir / f"{name}-sphere-{label}.png"
        write_png(png, side_by_side([meas_srgb, fit_srgb, to_srgb(np.abs(fit - meas), scale)]))
        captions[png.name] = f"{name}, {label}: " + sphere_caption(kind, d, meas, fit, spec, scale)
        layers = {"A": np.isfinite(fit[..., 0]).astype(np.float32)}
        planes = np.ascontiguousarray(np.stack([meas, fit, np.nan_to_num(fit - meas)]).transpose(0, 3, 1, 2),
                                      dtype=np.float32)                           # (layer, channel, h, w)
        for k, layer in enumerate(("measured", "fitted", "difference")):
            layers.update({f"{layer}.{c}": planes[k, i] for i, c in enumerate("RGB")})
        exr = out_dir / f"{name}-sphere-{label}.exr"
        write_exr(exr, layers, compression="rle")
        paths += [png, exr]
    paths.append(out_dir / f"{name}-thumb.png")
    write_png(paths[-1], thumb, (2 * THUMB_SIZE, THUMB_SIZE))
    return paths, captions
