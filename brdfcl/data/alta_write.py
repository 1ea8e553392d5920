"""ALTA's text data format written: the inverse of brdfcl.data.alta's reader.

One header (``#DIM``, ``#PARAM_IN``, ``#PARAM_OUT``, ``#VS 0``: no confidence columns), comment
lines (``#`` and a space, which ALTA and brdfcl skip), then one row per point: its coordinates in
the parametrisation, then its outputs.  Numbers are written with 17 significant digits, so that
reading the file back gives the same float64 values.  A value that is not a finite non-negative
number (no BRDF there: a direction pair below the horizon) is written -1, the mark of a missing
value that brdfcl's reader, like MERL tables, leaves out.
"""
from __future__ import annotations

import io
from collections.abc import Iterable

import numpy as np

from brdfcl.data.alta import OUTPUTS
from brdfcl.data.alta_params import PARAMS

MISSING = -1.0
"""What a point without a value is written as."""


def alta_text(param_in: str, x: np.ndarray, values: np.ndarray, param_out: str,
              comments: Iterable[str] = ()) -> str:
    """The text of an ALTA data file: rows ``x`` (n, PARAMS[param_in]) in ``param_in`` with
    ``values`` (n, outputs of ``param_out``); ValueError if the shapes do not fit the names."""
    if param_in not in PARAMS:
        raise ValueError(f"ALTA parametrisation {param_in!r}: brdfcl writes {', '.join(PARAMS)}")
    if param_out not in OUTPUTS:
        raise ValueError(f"ALTA output {param_out!r}: brdfcl writes {', '.join(OUTPUTS)}")
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    values = np.asarray(values, dtype=np.float64).reshape(len(values), -1)
    n_in, n_out = PARAMS[param_in], len(OUTPUTS[param_out])
    if x.shape[1] != n_in or values.shape != (len(x), n_out):
        raise ValueError(f"{param_in} rows need {n_in} coordinates and {param_out} {n_out} values each: "
                         f"got coordinates {x.shape} and values {values.shape}")
    values = np.where(np.isfinite(values) & (values >= 0), values, MISSING)
    out = io.StringIO()
    out.write(f"#DIM {n_in} {n_out}\n#PARAM_IN {param_in}\n#PARAM_OUT {param_out}\n#VS 0\n")
    for line in comments:
        out.write(f"# {' '.join(str(line).split())}\n")
    np.savetxt(out, np.hstack([x, values]), fmt="%.17g")
    return out.getvalue()
