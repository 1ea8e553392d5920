"""How every output file is written: atomically, and a failed write as one line naming the file.

A run stopped at any moment leaves each output either as it was or complete: files are written
under a temporary name beside them and renamed into place (``atomic_write_text``, ``write_exr``;
the figures do the same).  A temporary file left by a killed run is removed by the next run
(``remove_stale_temporaries``).  A write that fails (a full disk, a read-only folder, a folder
where the file goes) is an OSError of one line, ``PATH: cannot write: why`` (``writing``).
"""
from __future__ import annotations

import os
import re
import struct
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

_TEMPORARY = re.compile(r"\.tmp\d+$|\.tmp\.(exr|png)$")


@contextmanager
def writing(path: str | os.PathLike) -> Iterator[None]:
    """A failed write of ``path`` as one line naming it (OpenEXR reports I/O errors as RuntimeError)."""
    try:
        yield
    except (OSError, RuntimeError) as e:
        why = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        why = (why.strip().splitlines() or [type(e).__name__])[0]
        raise OSError(f"{path}: cannot write: {why}") from e


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file beside it (``.NAME.tmpPID``)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_exr(path: str | os.PathLike, channels: dict[str, np.ndarray], compression: str = "zip") -> None:
    """float32 images, one per named channel, into one OpenEXR file, atomically; NaN written as -1.
    ``compression``: "zip" (smallest), "rle" (a third of zip's time, a fifth larger) or "none"."""
    # local: only the analysis and the report pages write EXR
    import OpenEXR
    data = {k: _plane(v) for k, v in channels.items()}
    methods = {"zip": OpenEXR.ZIP_COMPRESSION, "rle": OpenEXR.RLE_COMPRESSION, "none": OpenEXR.NO_COMPRESSION}
    hdr = {"compression": methods[compression], "type": OpenEXR.scanlineimage}
    tmp = str(path) + ".tmp.exr"
    with writing(path):
        with OpenEXR.File(hdr, data) as f:
            f.write(tmp)
        Path(tmp).replace(path)


def _plane(v) -> np.ndarray:
    """An image as OpenEXR takes it: C-contiguous float32, NaN as -1 (a copy only where needed)."""
    v = np.ascontiguousarray(v, dtype=np.float32)
    return v if np.isfinite(v).all() else np.nan_to_num(v, nan=-1.0)


def png_bytes(rgb: np.ndarray, level: int = 1) -> bytes:
    """An 8-bit RGB image (h, w, 3) as a PNG file's bytes: each row filtered with PNG's Sub
    filter (every byte less the one a pixel to its left, modulo 256) and compressed by zlib at
    ``level``; half of an encoder's time that tries every filter on every row, for a file a few
    percent larger."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    h, w, channels = rgb.shape
    if channels != 3:
        raise ValueError(f"an RGB image has 3 channels, not {channels}")
    rows = rgb.reshape(h, 3 * w)
    data = np.empty((h, 3 * w + 1), np.uint8)
    data[:, 0] = 1                                   # filter type: Sub
    data[:, 1:4] = rows[:, :3]
    np.subtract(rows[:, 3:], rows[:, :-3], out=data[:, 4:])    # uint8: modulo 256

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(data.tobytes(), level)) + chunk(b"IEND", b""))


def write_png(path: str | os.PathLike, rgb: np.ndarray) -> None:
    """An 8-bit RGB image (h, w, 3) into a PNG file (`png_bytes`), atomically."""
    tmp = f"{path}.tmp.png"
    with writing(path):
        Path(tmp).write_bytes(png_bytes(rgb))
        os.replace(tmp, path)


def remove_stale_temporaries(out_dir: str | os.PathLike) -> None:
    """Temporary files left by a run killed mid-write (``*.tmpPID``; final names are never partial)."""
    for p in Path(out_dir).iterdir():
        if p.is_file() and _TEMPORARY.search(p.name):
            try:
                p.unlink()
            except OSError:
                pass
