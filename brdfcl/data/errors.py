"""The one error a measurement file can raise, and the file checks every reader shares.

A malformed file gives a ``DataError`` whose message is one line naming the file, the line
where it applies, and the problem (``path:12: 34 numbers, expected 35``), never a numpy
traceback: a user fitting a folder of files must know at once which file to fix and how.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np


class DataError(ValueError):
    """A measurement file that cannot be used; the message is one line: file, line, problem."""

    def __init__(self, path: str | os.PathLike[str] | None, problem: str, line: int | None = None):
        where = "<samples>" if path is None else os.fspath(path)
        if line is not None:
            where = f"{where}:{line}"
        self.path = None if path is None else os.fspath(path)
        self.line = line
        self.problem = " ".join(str(problem).split())          # one line, whatever it quotes
        super().__init__(f"{where}: {self.problem}")


def read_text(path: str | os.PathLike[str]) -> str:
    """The text of a measurement file; DataError if it is missing, unreadable, binary or empty.

    Measurement files are ASCII numbers: a NUL byte or bytes that are not UTF-8 mean a binary
    file given by mistake (a MERL table, a spreadsheet).  A UTF-8 byte-order mark (spreadsheet
    CSV exports) is dropped.  CRLF and CR line ends are read as LF."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except IsADirectoryError:
        raise DataError(path, "is a folder, not a file") from None
    except OSError as e:
        raise DataError(path, f"cannot read: {e.strerror or e}") from None
    if not data.strip():
        raise DataError(path, "empty file")
    if b"\x00" in data[:65536]:
        raise DataError(path, "binary data, not a text file of numbers")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise DataError(path, f"binary data, not a text file of numbers (byte {e.start} is not UTF-8)") from None
    return text.replace("\r\n", "\n").replace("\r", "\n")


def parse_numbers(path: str | os.PathLike[str], line: int, fields: list[str]) -> list[float]:
    """Floats of one line's fields; DataError naming the first field that is not a finite number."""
    out = []
    for k, f in enumerate(fields):
        try:
            x = float(f)
        except ValueError:
            raise DataError(path, f"field {k + 1} {_quote(f)} is not a number", line) from None
        if not math.isfinite(x):
            raise DataError(path, f"field {k + 1} is {f.strip()}: values must be finite numbers", line)
        out.append(x)
    return out


def _quote(text: str, limit: int = 20) -> str:
    text = text.strip()
    return repr(text if len(text) <= limit else text[:limit] + "...")


def parse_rows(path, rows, width: int, wrong_width, none_left: str):
    """(values (n, width) float64, line numbers) of numbered rows of fields ``[(line, fields)]``;
    a row of another width is ``DataError(path, wrong_width(n_fields), line)``, no row at all
    ``DataError(path, none_left)``."""
    values, lines = [], []
    for k, fields in rows:
        if len(fields) != width:
            raise DataError(path, wrong_width(len(fields)), k)
        values.append(parse_numbers(path, k, fields))
        lines.append(k)
    if not values:
        raise DataError(path, none_left)
    return np.array(values, dtype=np.float64), lines
