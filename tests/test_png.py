"""The report's PNG writer: files any decoder reads back to the same pixels."""
import io

import numpy as np
import pytest
from PIL import Image

from brdfcl.report.files import png_bytes, write_png


@pytest.mark.parametrize("shape", [(1, 1, 3), (7, 5, 3), (64, 392, 3)])
def test_png_round_trip(shape):
    rgb = np.random.default_rng(sum(shape)).integers(0, 256, shape, dtype=np.uint8)
    rgb[..., 0] = 255 - rgb[..., 0] // 7          # differences that wrap around modulo 256
    back = Image.open(io.BytesIO(png_bytes(rgb)))
    assert back.mode == "RGB" and back.size == (shape[1], shape[0])
    np.testing.assert_array_equal(np.asarray(back), rgb)


def test_write_png_is_atomic_and_says_which_file(tmp_path):
    path = tmp_path / "a.png"
    rgb = np.zeros((4, 6, 3), np.uint8)
    rgb[1, 2] = (10, 200, 30)
    write_png(path, rgb)
    np.testing.assert_array_equal(np.asarray(Image.open(path)), rgb)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]
    with pytest.raises(OSError, match=r"missing.*b\.png: cannot write"):
        write_png(tmp_path / "missing" / "b.png", rgb)


def test_png_wants_rgb():
    with pytest.raises(ValueError, match="3 channels"):
        png_bytes(np.zeros((2, 2, 4), np.uint8))
