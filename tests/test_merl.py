import filecmp
import os
import time
import tracemalloc

import numpy as np
import pytest

from brdfcl.data import merl
from brdfcl.data.merl import (
    FILE_SIZE,
    MAP_BELOW,
    N_CELLS,
    SCALE,
    MerlError,
    read_database,
    read_merl,
    read_merl_at,
    read_merl_cells,
    write_merl,
)


def test_proxy_round_trip_is_identical(proxy_pair, tmp_path):
    for src in proxy_pair:
        t = read_merl(src)
        assert t.stored.shape == (3, N_CELLS)
        assert 0 < t.n_missing < N_CELLS
        out = tmp_path / src.name
        write_merl(out, t)
        assert filecmp.cmp(src, out, shallow=False)


def test_read_speed_and_single_float64_copy(proxy_pair):
    tracemalloc.start()
    t0 = time.perf_counter()
    t = read_merl(proxy_pair[0])
    dt = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    one_copy = 3 * N_CELLS * 8
    # a second float64 copy would double the peak; boolean masks add 1/8 each
    assert peak < 1.3 * one_copy, f"peak {peak / 2**20:.1f} MiB for a {one_copy / 2**20:.1f} MiB table"
    assert dt < 3.0
    assert np.isnan(t.stored).sum() == 3 * t.n_missing


def test_missing_values_counted_and_scaled(tmp_path):
    brdf = np.full((3, N_CELLS), 0.25)
    brdf[:, 10] = np.nan
    write_merl(tmp_path / "a.binary", brdf)
    raw = np.fromfile(tmp_path / "a.binary", dtype="<f8", offset=12).reshape(3, N_CELLS)
    raw[1, 20] = np.inf
    raw[2, 30] = -0.5
    raw[0, 40] = np.nan
    with open(tmp_path / "b.binary", "wb") as f:
        f.write(np.array([90, 90, 180], "<i4").tobytes() + raw.tobytes())
    t = read_merl(tmp_path / "b.binary")
    assert t.n_missing == 4
    assert t.name == "b"
    ok = t.valid
    np.testing.assert_allclose(t.brdf()[:, ok], 0.25, rtol=1e-15)
    assert t.stored[0, 0] == pytest.approx(0.25 / SCALE[0])
    cells = np.array([0, 10, 20, 30, 40, 50, N_CELLS - 1])            # a few cells, without the table
    for _ in range(2):                                                # the second read reuses the buffer
        np.testing.assert_array_equal(read_merl_cells(tmp_path / "b.binary", cells), t.brdf_at(cells))


@pytest.mark.parametrize("content, message", [
    (b"", "not a MERL file"),
    (np.array([90, 90, 90], "<i4").tobytes() + b"\0" * 64, "wrong header"),
    (np.array([90, 90, 180], "<i4").tobytes() + b"\0" * 64, "wrong size"),
    (b"hello, this is not a brdf at all", "wrong header"),
])
def test_bad_files_name_file_and_problem(tmp_path, content, message):
    p = tmp_path / "bad.binary"
    p.write_bytes(content)
    with pytest.raises(MerlError) as e:
        read_merl(p)
    assert str(p) in str(e.value) and message in str(e.value)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("many", [False, True], ids=["mapped", "read whole"])
def test_values_at_cells_equal_the_tables(tmp_path, dtype, many):
    """read_merl_at (what fit-all and the report read through) gives the table's values at each
    index set, missing cells (negative, NaN, inf in any channel) NaN, in float32 or float64: a few
    cells taken from the file mapped into memory, many from the file read whole into a reused
    buffer."""
    rng = np.random.default_rng(3)
    raw = rng.uniform(0.0, 300.0, size=(3, N_CELLS))
    raw[0, 5], raw[1, 7], raw[2, 9] = -1.0, np.nan, np.inf
    with open(tmp_path / "m.binary", "wb") as f:
        f.write(np.array([90, 90, 180], "<i4").tobytes() + raw.astype("<f8").tobytes())
    t = read_merl(tmp_path / "m.binary")
    n = MAP_BELOW if many else 1000
    sets = [np.arange(0, 50), np.sort(rng.choice(N_CELLS, n, replace=False))]
    outs = [np.zeros((3, ix.size), dtype) for ix in sets]
    buffer = np.full(3 * N_CELLS, 7.0)
    for _ in range(2):                                         # the buffer reused
        assert read_merl_at(tmp_path / "m.binary", sets, outs, buffer) == "m"
        for o, ix in zip(outs, sets):
            want = t.brdf_at(ix, dtype)
            np.testing.assert_array_equal(np.isnan(o), np.isnan(want))
            np.testing.assert_allclose(o, want, rtol=1e-7 if dtype == np.float32 else 1e-15)
    assert np.isnan(outs[0][:, [5, 7, 9]]).sum() == 3
    if many:
        with pytest.raises(ValueError, match="read buffer"):
            read_merl_at(tmp_path / "m.binary", sets, outs, np.empty(10))


def test_file_cut_short_after_its_check_names_the_file(tmp_path, monkeypatch):
    """A file that changes size between its check and its mapping: one line naming it."""
    write_merl(tmp_path / "m.binary", np.full((3, N_CELLS), 0.5))
    monkeypatch.setattr(merl, "_check_header", lambda path, f, size: os.truncate(path, FILE_SIZE - 8))
    with pytest.raises(MerlError, match=r"m.binary: file changed while reading"):
        read_merl_cells(tmp_path / "m.binary", np.arange(10))


def test_all_missing_in_the_fitted_cells_is_an_error(tmp_path):
    brdf = np.full((3, N_CELLS), np.nan)
    brdf[:, -1] = 0.5                                          # valid outside the cells read
    write_merl(tmp_path / "x.binary", brdf)
    outs = [np.empty((3, 100), np.float32)]
    with pytest.raises(MerlError, match=r"x.binary: every cell is missing within the fitted region"):
        read_merl_at(tmp_path / "x.binary", [np.arange(100)], outs)
    brdf[1, 3] = 0.5
    brdf[0, 4] = 0.5                                           # each cell still missing in a channel
    write_merl(tmp_path / "x.binary", brdf)
    with pytest.raises(MerlError, match="every cell is missing"):
        read_merl_at(tmp_path / "x.binary", [np.arange(100)], outs)


def test_all_missing_is_an_error(tmp_path):
    write_merl(tmp_path / "x.binary", np.full((3, N_CELLS), np.nan))
    assert (tmp_path / "x.binary").stat().st_size == FILE_SIZE
    with pytest.raises(MerlError, match="every cell is missing"):
        read_merl(tmp_path / "x.binary")


def test_database_reads_good_and_reports_bad(tmp_path):
    write_merl(tmp_path / "good.binary", np.full((3, N_CELLS), 0.1))
    (tmp_path / "bad.binary").write_bytes(b"xx")
    (tmp_path / "notes.txt").write_text("ignored")
    tables, errors = read_database(tmp_path)
    assert [t.name for t in tables] == ["good"]
    assert list(errors) == [str(tmp_path / "bad.binary")]
    (tmp_path / "empty").mkdir()
    with pytest.raises(MerlError, match="no .binary files"):
        read_database(tmp_path / "empty")
