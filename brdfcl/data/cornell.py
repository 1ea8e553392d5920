"""Reader and writer of the Cornell ``.brdf`` ASCII format of spectral gonioreflectometer
measurements.

Layout (as read by pbrt-v2's measured BRDF, which ships such files)::

    # comments start with '#', anywhere on a line; blank lines are ignored
    31                                   the number N of wavelengths
    400 410 ... 700                      N wavelengths in nm, wrapped over any number of lines
    theta_i phi_i theta_s phi_s v_1 ... v_N      one sample per line, angles in radians

``v_k`` is the BRDF (1/sr) at wavelength k.  theta_i, theta_s must lie in [0, pi/2] and phi in
[-2 pi, 2 pi]; ``phi`` of both directions is measured in one frame (phi_s = phi_i + pi is the
specular side).  The count may share its line with the first wavelengths.  Unlike pbrt's
token-stream reader, a sample must sit on one line: a wrong column count is then reported at
the line that has it instead of shifting every later sample.

``write_cornell`` writes ``Samples`` of spectral bands in this layout, every number with Python's
shortest round-trip repr, so that ``read_cornell`` gives back the same angles, values and
wavelengths exactly (brdfcl synth --like writes synthetic materials with it).
"""
from __future__ import annotations

import os

import numpy as np

from brdfcl._version import __version__
from brdfcl._words import noun

from .errors import DataError, parse_numbers, parse_rows, read_text
from .samples import RGB_WAVELENGTHS_UM, Channel, Samples, make_samples

SUFFIX = ".brdf"
WAVELENGTH_RANGE_NM = (100.0, 100000.0)
"""Wavelengths outside this range are refused: they are not nm (um given by mistake, say)."""


def read_cornell(path: str | os.PathLike[str]) -> Samples:
    """Read one Cornell ``.brdf`` file; DataError (one line: file, line, problem) if malformed."""
    lines = [(k + 1, line.split("#", 1)[0].split()) for k, line in enumerate(read_text(path).split("\n"))]
    lines = [(k, fields) for k, fields in lines if fields]
    if not lines:
        raise DataError(path, "no numbers: only comments and blank lines")

    k0, first = lines[0]
    try:
        count_f = float(first[0])
    except ValueError:
        count_f = float("nan")
    if not (np.isfinite(count_f) and count_f == int(count_f)):
        raise DataError(path, f"expected the number of wavelengths, found {first[0][:20]!r}", k0)
    count = int(count_f)
    if count < 1:
        raise DataError(path, f"number of wavelengths {count}: must be at least 1", k0)

    wls: list[float] = []
    wl_lines: list[int] = []
    pending = [(k0, first[1:])] + lines[1:]
    body = len(pending)
    for j, (k, fields) in enumerate(pending):
        take = fields[: count - len(wls)]
        wls += parse_numbers(path, k, take)
        wl_lines += [k] * len(take)
        if len(wls) == count:
            if len(take) < len(fields):
                extra = len(fields) - len(take)
                raise DataError(path, f"the header announces {count} wavelengths but the list does not end "
                                      f"there: {extra} more {noun(extra, 'number')} on this line "
                                      "(the count and the list disagree)", k)
            body = j + 1
            break
    else:
        raise DataError(path, f"the header announces {count} wavelengths but the file holds only {len(wls)} "
                              "numbers after it: no samples")
    channels = _channels(path, wls, wl_lines)

    width = 4 + count
    a, where = parse_rows(path, pending[body:], width,
                          lambda n: f"{n} numbers, expected {width} (4 angles + {count} values)",
                          "no samples after the wavelength list")
    return make_samples(path, a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4:], channels, lines=where)


read_cornell.format_name = "Cornell {} samples"  # type: ignore[attr-defined]


def _channels(path: str | os.PathLike[str], wls_nm: list[float], lines: list[int]) -> tuple[Channel, ...]:
    lo, hi = WAVELENGTH_RANGE_NM
    seen: set[float] = set()
    for x, line in zip(wls_nm, lines):
        if x <= 0:
            raise DataError(path, f"{'negative' if x < 0 else 'zero'} wavelength {x:g} nm", line)
        if not lo <= x <= hi:
            raise DataError(path, f"wavelength {x:g} nm out of range [{lo:g}, {hi:g}] nm (the format gives nm)",
                            line)
        if x in seen:
            raise DataError(path, f"repeated wavelength {x:g} nm", line)
        seen.add(x)
    return tuple(Channel(f"{x:g}nm", x / 1000.0) for x in wls_nm)


WAVELENGTHS_PER_LINE = 10


def write_cornell(samples: Samples, path: str | os.PathLike[str]) -> None:
    """Write spectral samples in the Cornell format: a ``#`` header saying what wrote it, the
    number of bands, their wavelengths in nm, then ``theta_i phi_i theta_s phi_s v_1 .. v_C`` per
    sample (radians, BRDF in 1/sr), every number as Python's shortest round-trip repr.

    ValueError (one line) for what the format cannot hold: channels that are not spectral bands
    (R, G, B) or whose wavelength is missing, out of range or repeated, and values that are not
    finite numbers."""
    nm = [_wavelength_nm(samples, c) for c in samples.channels]
    if not nm:
        raise ValueError(f"{samples.name}: no channel to write in the Cornell format")
    if len(set(nm)) != len(nm):
        raise ValueError(f"{samples.name}: two channels share a wavelength; the Cornell format names "
                         "bands by their wavelength")
    values = np.asarray(samples.values, dtype=np.float64)
    if not np.isfinite(values).all():
        raise ValueError(f"{samples.name}: values with NaN or infinity (missing values) cannot be written "
                         "in the Cornell format")
    table = np.column_stack([samples.theta_i, samples.phi_i, samples.theta_o, samples.phi_o, values]).tolist()
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(f"# written by brdfcl {__version__} (brdfcl.data.cornell.write_cornell): "
                f"{' '.join(samples.name.split())}\n"
                f"# {samples.n_samples} samples; angles in radians, values: BRDF in 1/sr\n\n"
                f"# num wls\n{len(nm)}\n\n# wls\n")
        for s in range(0, len(nm), WAVELENGTHS_PER_LINE):
            f.write(" ".join(nm[s:s + WAVELENGTHS_PER_LINE]) + "\n")
        f.write("\n# theta i, phi i, theta s, phi s, spectral sample values\n\n")
        for row in table:
            f.write(" ".join(repr(float(x)) for x in row) + "\n")


def _wavelength_nm(samples: Samples, c: Channel) -> str:
    """A channel's wavelength in nm as written: a number that reads back as the same um."""
    um = getattr(c, "wavelength_um", None)
    if um is None or not np.isfinite(um) or um <= 0:
        raise ValueError(f"{samples.name}: channel {c.name!r} has no wavelength; the Cornell format needs "
                         "one per band")
    if c.name.upper() in RGB_WAVELENGTHS_UM:
        raise ValueError(f"{samples.name}: channel {c.name!r} is not a spectral band (R, G, B); the Cornell "
                         "format holds spectral samples only (write them as CSV)")
    x = float(um) * 1000.0
    lo, hi = WAVELENGTH_RANGE_NM
    if not lo <= x <= hi:
        raise ValueError(f"{samples.name}: channel {c.name!r} at {x:g} nm is out of the range "
                         f"[{lo:g}, {hi:g}] nm of the Cornell format")
    for y in (x, np.nextafter(x, np.inf), np.nextafter(x, -np.inf)):   # the nm that reads back as um
        if float(repr(float(y))) / 1000.0 == um:
            return repr(float(y))
    return repr(x)
