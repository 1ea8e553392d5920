"""A plain CSV of scattered samples: what a user with their own instrument can write.

Format (comma separated, UTF-8 or ASCII)::

    # lines starting with '#' are comments; blank lines are ignored
    theta_i,phi_i,theta_o,phi_o,450nm,550nm,650nm
    30,0,30,180,0.81,0.62,0.40
    30,0,45,180,0.12,0.10,0.08

* The first four columns are ``theta_i, phi_i, theta_o, phi_o`` in that order (``theta_s``,
  ``phi_s`` are accepted for the outgoing direction).  Angles are in **degrees** unless a column
  says ``[rad]`` (``theta_i[rad]``; ``[deg]`` may be written too): degrees are what people
  type and read, radians are there for exact round trips.  theta in [0, 90] deg, phi in
  [-360, 360] deg, both directions' phi in one frame (phi_o = phi_i + 180 is the specular side).
* Every further column is one channel, named by its wavelength: ``450nm``, ``0.45um`` (or
  ``µm``), a bare number meaning nm, or ``R``, ``G``, ``B`` (linear RGB, effective wavelengths
  0.645, 0.526, 0.444 um).  Values are the BRDF in 1/sr; every field must be a finite number.
* Weights are not stored: they follow from the angles (``weights.sample_weights``).
"""
from __future__ import annotations

import csv
import os
import re

import numpy as np

from .errors import DataError, parse_rows, read_text
from .samples import RGB_WAVELENGTHS_UM, Channel, Samples, make_samples

SUFFIX = ".csv"
WAVELENGTH_RANGE_NM = (100.0, 100000.0)
ANGLES = ("theta_i", "phi_i", "theta_o", "phi_o")
_ALIASES = {"theta_s": "theta_o", "phi_s": "phi_o"}
_ANGLE_RE = re.compile(r"^([a-z_]+)\s*(?:[\[(]\s*(deg|degrees|rad|radians)\s*[\])])?$", re.IGNORECASE)
_WAVE_RE = re.compile(r"^([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?|-[0-9.eE+-]+)\s*(nm|um|µm|μm)?$", re.IGNORECASE)


def read_csv(path: str | os.PathLike[str]) -> Samples:
    """Read a samples CSV; DataError (one line: file, line, problem) if malformed."""
    numbered = [(k + 1, line) for k, line in enumerate(read_text(path).split("\n"))]
    numbered = [(k, line) for k, line in numbered if line.strip() and not line.lstrip().startswith("#")]
    if not numbered:
        raise DataError(path, "no header: only comments and blank lines")
    rows = list(csv.reader([line for _, line in numbered]))
    (k0, _), header = numbered[0], [f.strip() for f in rows[0]]
    to_rad = _angle_units(path, header, k0)
    channels = tuple(_channel(path, f, j + 5, k0) for j, f in enumerate(header[4:]))
    if not channels:
        raise DataError(path, "no channel column after theta_i, phi_i, theta_o, phi_o", k0)
    if len({c.name for c in channels}) != len(channels):
        raise DataError(path, "repeated channel column", k0)

    a, where = parse_rows(path, [(k, f) for (k, _), f in zip(numbered[1:], rows[1:])], len(header),
                          lambda n: f"{n} columns, expected {len(header)} as in the header",
                          "no samples after the header")
    ti, pi_, to, po = (a[:, j] * to_rad[j] for j in range(4))
    return make_samples(path, ti, pi_, to, po, a[:, 4:], channels, lines=where)


read_csv.format_name = "{} samples"  # type: ignore[attr-defined]


def write_csv(samples: Samples, path: str | os.PathLike[str], *, radians: bool = False) -> None:
    """Write samples in the format above (degrees, or radians with ``[rad]`` headers); values
    are written with Python's shortest round-trip repr, so radians round trip exactly."""
    angles = [samples.theta_i, samples.phi_i, samples.theta_o, samples.phi_o]
    if radians:
        names = [f"{a}[rad]" for a in ANGLES]
    else:
        names, angles = list(ANGLES), [np.degrees(a) for a in angles]
    names += [_column_name(c) for c in samples.channels]
    table = np.column_stack(angles + [samples.values]).tolist()
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(f"# brdfcl samples: {samples.name}; angles in {'radians' if radians else 'degrees'}, "
                "values: BRDF in 1/sr\n")
        f.write(",".join(names) + "\n")
        for row in table:
            f.write(",".join(repr(x) for x in row) + "\n")


def _column_name(c: Channel) -> str:
    if RGB_WAVELENGTHS_UM.get(c.name) == c.wavelength_um:
        return c.name
    return f"{c.wavelength_um * 1000.0:.12g}nm"


def _angle_units(path: str | os.PathLike[str], header: list[str], line: int) -> list[float]:
    """Factor to radians of each of the first four columns; DataError if they are not the angles."""
    factors = []
    for j, want in enumerate(ANGLES):
        got = header[j] if j < len(header) else ""
        m = _ANGLE_RE.match(got)
        name = "" if m is None else _ALIASES.get(m.group(1).lower(), m.group(1).lower())
        if m is None or name != want:
            hint = ("columns are separated by commas" if len(header) == 1 and any(c in got for c in ";\t|")
                    else f"{want}[deg] or {want}[rad] also do; then one column per channel")
            raise DataError(path, f"header column {j + 1} is {got[:30]!r}, expected {want} ({hint})", line)
        unit = (m.group(2) or "deg").lower()
        factors.append(1.0 if unit.startswith("rad") else np.pi / 180.0)
    return factors


def _channel(path: str | os.PathLike[str], field: str, column: int, line: int) -> Channel:
    if field.upper() in RGB_WAVELENGTHS_UM:
        return Channel(field.upper(), RGB_WAVELENGTHS_UM[field.upper()])
    m = _WAVE_RE.match(field)
    if not m:
        raise DataError(path, f"header column {column} {field[:30]!r} is neither a wavelength "
                              "(450nm, 0.45um, 450) nor R, G or B", line)
    try:
        x = float(m.group(1))
    except ValueError:
        raise DataError(path, f"header column {column} {field[:30]!r} is not a wavelength", line) from None
    um = x / 1000.0 if (m.group(2) or "nm").lower() == "nm" else x
    nm = 1000.0 * um
    lo, hi = WAVELENGTH_RANGE_NM
    if nm <= 0:
        raise DataError(path, f"header column {column}: {'negative' if nm < 0 else 'zero'} wavelength "
                              f"{field!r}", line)
    if not lo <= nm <= hi:
        raise DataError(path, f"header column {column}: wavelength {field!r} out of range "
                              f"[{lo:g}, {hi:g}] nm", line)
    return Channel(f"{nm:g}nm", um)
