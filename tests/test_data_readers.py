"""Readers of scattered measurements: Cornell .brdf, samples CSV, the suffix registry, and a
one-line DataError naming the file for every malformed file."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from brdfcl.data import readers
from brdfcl.data.cornell import read_cornell
from brdfcl.data.csvsamples import read_csv, write_csv
from brdfcl.data.errors import DataError
from brdfcl.data.merl import MerlError
from brdfcl.data.readers import READERS, find_measurements, read_samples
from brdfcl.data.samples import Channel, make_samples, rgb_channels
from brdfcl.data.weights import DOMAIN_MEASURE
from tests.conftest import KRYLON

# ---------------------------------------------------------------- Cornell


def test_krylon_blue(krylon):
    s = krylon
    assert s.name == "krylon_blue" and s.path == str(KRYLON)
    assert s.n_samples == 1439 and s.n_channels == 31
    np.testing.assert_allclose(s.wavelengths, np.arange(400, 701, 10) / 1000)
    assert s.channels[0] == Channel("400nm", 0.4)
    assert np.degrees(s.theta_i.min()) == pytest.approx(10, abs=1e-3)
    assert np.degrees(s.theta_i.max()) == pytest.approx(80, abs=1e-3)
    assert sorted(np.unique(np.round(np.degrees(s.theta_i)))) == [10, 20, 30, 40, 50, 60, 70, 80]
    assert (s.phi_i == 0).all() and np.abs(s.phi_o).max() > 3.0       # in and out of plane
    # the first sample line of the file
    assert (s.theta_i[0], s.phi_i[0], s.theta_o[0], s.phi_o[0]) == (0.872665, 0.0, 0.573513, 0.0)
    assert (s.values[0, 0], s.values[0, 1], s.values[0, -1]) == (0.017415, 0.036844, 0.005187)
    assert np.isfinite(s.values).all() and s.values.min() >= 0 and s.values.max() > 60   # a specular peak
    # weights: positive, bounded by the cap, covering nearly the whole domain
    w = s.weights
    assert (w > 0).all() and w.max() <= 10 * np.median(w) * (1 + 1e-12)
    assert 0.95 * DOMAIN_MEASURE < w.sum() <= DOMAIN_MEASURE * (1 + 1e-12)
    # within the default 80 deg cut-off, the theta_i = 80 deg samples no longer stand for the
    # grazing band beyond it (every sample is inside: 80 deg is written as 1.396263 < 80 deg)
    inner = s.weights_within(80)
    assert s.mask(80).all() and (inner > 0).all()
    assert 0.95 * DOMAIN_MEASURE * (1 - np.cos(np.radians(80))) ** 2 < inner.sum()
    edge = np.round(np.degrees(s.theta_i)) == 80
    assert w[edge].sum() / w.sum() > 0.25 and inner[edge].sum() / inner.sum() < 0.1


def test_krylon_rgb_is_blue(krylon):
    pytest.importorskip("colour")
    from brdfcl.data.rgb import to_rgb
    rgb = to_rgb(krylon)
    med = np.median(rgb.values[krylon.mask()], axis=0)
    assert med[2] > 3 * med[1] and med[1] > med[0]


def _cornell(tmp_path, text, name="m.brdf", newline="\n"):
    p = tmp_path / name
    p.write_bytes(text.replace("\n", newline).encode())
    return p


CANON = """# three wavelengths
3
450 550 650
0.1 0 0.2 3.14 0.5 0.6 0.7
0.3 0 0.4 1.0 0.05 0.06 0.07
"""


@pytest.mark.parametrize("variant", [
    # wavelength list wrapped over lines, comments everywhere, CRLF
    ("# header\n\n3 # count\n# wls\n450\n550 650\n\n# samples\n0.1 0 0.2 3.14 0.5 0.6 0.7  # first\n"
     "\n0.3 0 0.4 1.0 0.05 0.06 0.07\n", "\r\n"),
    ("3 450 550 650\n0.1 0 0.2 3.14 0.5 0.6 0.7\n0.3 0 0.4 1.0 0.05 0.06 0.07", "\n"),   # count on the list's line
    ("3.0\n450\t550\t650\n0.1\t0\t0.2\t3.14\t0.5 0.6 0.7\n0.3 0 0.4 1.0 0.05 0.06 0.07\n", "\r"),
])
def test_cornell_header_variants(tmp_path, variant):
    text, newline = variant
    want = read_cornell(_cornell(tmp_path, CANON, "canon.brdf"))
    got = read_cornell(_cornell(tmp_path, text, newline=newline))
    assert got.channels == want.channels == (Channel("450nm", 0.45), Channel("550nm", 0.55), Channel("650nm", 0.65))
    for f in ("theta_i", "phi_i", "theta_o", "phi_o", "values", "weights"):
        np.testing.assert_array_equal(getattr(got, f), getattr(want, f))


def test_cornell_any_number_of_wavelengths(tmp_path):
    one = read_cornell(_cornell(tmp_path, "1\n550\n0.1 0 0.2 0 0.3\n"))
    assert one.n_channels == 1 and one.values.tolist() == [[0.3]]
    wl = np.arange(380, 781, 5)
    rows = "\n".join(" ".join(["0.5", "0", "0.5", "3.14159"] + [f"{0.01 * k}" for k in range(wl.size)])
                     for _ in range(4))
    many = read_cornell(_cornell(tmp_path, f"{wl.size}\n" + "\n".join(map(str, wl)) + "\n" + rows + "\n"))
    assert many.n_channels == 81 and many.n_samples == 4
    np.testing.assert_allclose(many.wavelengths, wl / 1000)


# ---------------------------------------------------------------- CSV


def test_csv_round_trip(tmp_path):
    rng = np.random.default_rng(11)
    n = 40
    ti, to = np.arccos(rng.uniform(0.01, 1, (2, n)))
    pi_, po = rng.uniform(-np.pi, np.pi, (2, n))
    values = rng.uniform(0, 5, (n, 4))
    ch = (Channel("400nm", 0.4), Channel("512.5nm", 0.5125), Channel("650nm", 0.65), Channel("1200nm", 1.2))
    s = make_samples(tmp_path / "orig.csv", ti, pi_, to, po, values, ch)
    write_csv(s, tmp_path / "rad.csv", radians=True)
    back = read_csv(tmp_path / "rad.csv")
    assert back.name == "rad" and back.channels == ch
    for f in ("theta_i", "phi_i", "theta_o", "phi_o", "values", "weights"):
        np.testing.assert_array_equal(getattr(back, f), getattr(s, f))          # exact in radians
    write_csv(s, tmp_path / "deg.csv")
    deg = read_csv(tmp_path / "deg.csv")
    assert "theta_i,phi_i,theta_o,phi_o,400nm,512.5nm,650nm,1200nm" in (tmp_path / "deg.csv").read_text()
    np.testing.assert_allclose(deg.theta_o, s.theta_o, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(deg.phi_i, s.phi_i, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(deg.values, s.values)
    # RGB samples keep their R, G, B columns
    rgb = make_samples(None, ti, pi_, to, po, values[:, :3], rgb_channels())
    write_csv(rgb, tmp_path / "rgb.csv")
    assert ",R,G,B" in (tmp_path / "rgb.csv").read_text()
    assert read_csv(tmp_path / "rgb.csv").channels == rgb_channels()


def test_csv_header_forms(tmp_path):
    p = tmp_path / "forms.csv"
    p.write_bytes("\ufeff# exported by hand\n\n THETA_I [rad], phi_i[rad],theta_s(rad) ,phi_s [radians],"
                  "450nm,0.55um,650, r ,\"700 nm\"\r\n# a comment between rows\r\n"
                  "0.5,0,0.6,3.14159,1,2,3,4,5\r\n".encode())
    s = read_csv(p)
    assert [c.name for c in s.channels] == ["450nm", "550nm", "650nm", "R", "700nm"]
    np.testing.assert_allclose(s.wavelengths, [0.45, 0.55, 0.65, 0.645, 0.7])
    assert (s.theta_i[0], s.theta_o[0], s.phi_o[0]) == (0.5, 0.6, 3.14159)
    q = tmp_path / "degrees.csv"
    q.write_text("theta_i,phi_i[deg],theta_o,phi_o,G\n30,0,45,180,0.25\n")
    d = read_csv(q)
    np.testing.assert_allclose([d.theta_i[0], d.theta_o[0], d.phi_o[0]], np.radians([30, 45, 180]))
    assert d.channels == (Channel("G", 0.526),)


# ---------------------------------------------------------------- malformed files

GOOD_ROW = "0.1 0 0.2 3.14 0.5 0.6 0.7"

CORNELL_BAD = {
    "empty": ("", "empty file"),
    "blank": ("\n  \n\t\n", "empty file"),
    "comments only": ("# nothing\n# here\n", "no numbers"),
    "count not a number": ("three\n450 550 650\n" + GOOD_ROW, r":1: expected the number of wavelengths"),
    "count zero": ("0\n" + GOOD_ROW, r":1: number of wavelengths 0"),
    "count fractional": ("2.5\n450 550 650\n" + GOOD_ROW, r":1: expected the number of wavelengths"),
    "more wavelengths than announced": ("3\n450 550 650 700\n" + GOOD_ROW,
                                        r":2: the header announces 3 wavelengths but the list does not end there"),
    "fewer wavelengths than announced": ("4\n450 550 650\n" + GOOD_ROW, r":3: the header announces 4 wavelengths"),
    "list runs out": ("40\n450 550 650\n", "announces 40 wavelengths but the file holds only 3"),
    "negative wavelength": ("3\n450 -550 650\n" + GOOD_ROW, r":2: negative wavelength -550 nm"),
    "zero wavelength": ("3 450 0 650\n" + GOOD_ROW, r":1: zero wavelength"),
    "wavelengths in um": ("3\n0.45 0.55 0.65\n" + GOOD_ROW, r"wavelength 0.45 nm out of range"),
    "repeated wavelength": ("3\n450\n550\n550\n" + GOOD_ROW, r":4: repeated wavelength 550 nm"),
    "nan wavelength": ("3\n450 nan 650\n" + GOOD_ROW, r":2: field 2 is nan"),
    "no samples": ("3\n450 550 650\n# none\n", "no samples"),
    "short row": ("3\n450 550 650\n" + GOOD_ROW + "\n0.1 0 0.2 3.14 0.5 0.6\n", r":4: 6 numbers, expected 7"),
    "long row": ("3\n450 550 650\n\n" + GOOD_ROW + " 0.8\n", r":4: 8 numbers, expected 7"),
    "nan value": ("3\n450 550 650\n" + GOOD_ROW + "\n0.1 0 0.2 3.14 0.5 NaN 0.7\n", r":4: field 6 is NaN"),
    "inf value": ("3\n450 550 650\n0.1 0 0.2 3.14 inf 0.6 0.7\n", r":3: field 5 is inf"),
    "text value": ("3\n450 550 650\n0.1 0 0.2 3.14 0.5 abc 0.7\n", r":3: field 6 'abc' is not a number"),
    "angles in degrees": ("3\n450 550 650\n" + GOOD_ROW + "\n30 0 20 180 0.5 0.6 0.7\n",
                          r":4: theta_i = 1718.87 deg \(30 rad\) is out of range \[0, 90\] deg"),
    "theta_o below the horizon": ("3\n450 550 650\n0.1 0 1.7 3.14 0.5 0.6 0.7\n", r":3: theta_o = 97.40\d* deg"),
    "negative theta": ("3\n450 550 650\n-0.1 0 0.2 3.14 0.5 0.6 0.7\n", r":3: theta_i = -5.7\d* deg"),
    "phi out of range": ("3\n450 550 650\n0.1 0 0.2 7 0.5 0.6 0.7\n", r":3: phi_o = 401.07\d* deg"),
}

CSV_HEAD = "theta_i,phi_i,theta_o,phi_o,450nm,550nm\n"
CSV_BAD = {
    "empty": ("", "empty file"),
    "comments only": ("# a\n#b\n", "no header"),
    "header only": (CSV_HEAD + "# no rows\n", "no samples after the header"),
    "angles not first": ("phi_i,theta_i,theta_o,phi_o,450nm\n0,10,20,180,1\n",
                         r":1: header column 1 is 'phi_i', expected theta_i"),
    "too few columns in header": ("theta_i,phi_i,theta_o\n10,0,20\n", r":1: header column 4 is '', expected phi_o"),
    "no channel": ("theta_i,phi_i,theta_o,phi_o\n10,0,20,180\n", r":1: no channel column"),
    "bad channel name": ("theta_i,phi_i,theta_o,phi_o,red\n10,0,20,180,1\n",
                         r":1: header column 5 'red' is neither a wavelength"),
    "negative wavelength": ("theta_i,phi_i,theta_o,phi_o,-450nm\n10,0,20,180,1\n",
                            r":1: header column 5: negative wavelength"),
    "unknown angle unit": ("theta_i[grad],phi_i,theta_o,phi_o,450\n10,0,20,180,1\n",
                           r":1: header column 1 .*theta_i\[rad\] also do"),
    "repeated channel": ("theta_i,phi_i,theta_o,phi_o,450nm,0.45um\n10,0,20,180,1,1\n", "repeated channel"),
    "short row": (CSV_HEAD + "10,0,20,180,1,2\n10,0,20,180,1\n", r":3: 5 columns, expected 6"),
    "trailing comma": (CSV_HEAD + "10,0,20,180,1,2,\n", r":2: 7 columns, expected 6"),
    "empty field": (CSV_HEAD + "10,0,,180,1,2\n", r":2: field 3 '' is not a number"),
    "nan": (CSV_HEAD + "10,0,20,180,nan,2\n", r":2: field 5 is nan"),
    "semicolons": ("theta_i;phi_i;theta_o;phi_o;450nm\n10;0;20;180;1\n", r":1: .*separated by commas"),
    "theta out of range": (CSV_HEAD + "10,0,20,180,1,2\n95,0,20,180,1,2\n", r":3: theta_i = 95 deg"),
    "radians declared, degrees given": ("theta_i[rad],phi_i[rad],theta_o[rad],phi_o[rad],450\n30,0,20,180,1\n",
                                        r":2: theta_i = 1718.87 deg"),
}


def _check_one_line(err, path, pattern):
    msg = str(err.value)
    assert "\n" not in msg and "Traceback" not in msg
    assert msg.startswith(str(path)), msg
    assert err.value.path == str(path)
    import re
    assert re.search(pattern, msg), msg


@pytest.mark.parametrize("case", sorted(CORNELL_BAD))
def test_malformed_cornell(tmp_path, case):
    text, pattern = CORNELL_BAD[case]
    p = _cornell(tmp_path, text, "bad file.brdf")
    with pytest.raises(DataError) as err:
        read_samples(p)
    _check_one_line(err, p, pattern)


@pytest.mark.parametrize("case", sorted(CSV_BAD))
def test_malformed_csv(tmp_path, case):
    text, pattern = CSV_BAD[case]
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(DataError) as err:
        read_samples(p)
    _check_one_line(err, p, pattern)


@pytest.mark.parametrize("suffix", [".brdf", ".csv"])
def test_unreadable_and_binary_files(tmp_path, suffix):
    cases = {
        "nul bytes": (b"3\n450 550 650\n\x00\x01\x02\x03", "binary data"),
        "not utf-8": (b"3\n450 550 650\n\xff\xfe\x80abc", "binary data"),
        "a MERL table": (np.array([90, 90, 180], "<i4").tobytes() + np.zeros(16).tobytes(), "binary data"),
    }
    for name, (data, pattern) in cases.items():
        p = tmp_path / f"{name}{suffix}"
        p.write_bytes(data)
        with pytest.raises(DataError) as err:
            read_samples(p)
        _check_one_line(err, p, pattern)
    missing = tmp_path / f"missing{suffix}"
    with pytest.raises(DataError) as err:
        read_samples(missing)
    _check_one_line(err, missing, "cannot read")
    folder = tmp_path / f"folder{suffix}"
    folder.mkdir()
    with pytest.raises(DataError) as err:
        read_samples(folder)
    _check_one_line(err, folder, "is a folder")


def test_unknown_suffix(tmp_path):
    p = tmp_path / "m.txt"
    p.write_text(CANON)
    with pytest.raises(DataError) as err:
        read_samples(p)
    _check_one_line(err, p, r"unknown format.*\.brdf, \.csv")


# ---------------------------------------------------------------- registry and folders


def test_registry_and_find_measurements(tmp_path, monkeypatch):
    (tmp_path / "a.brdf").write_text(CANON)
    (tmp_path / "B.CSV").write_text(CSV_HEAD + "10,0,20,180,1,2\n")
    (tmp_path / "notes.txt").write_text("x")
    (tmp_path / ".hidden.csv").write_text("x")
    (tmp_path / "table.binary").write_bytes(b"\x00")
    (tmp_path / "sub.csv").mkdir()
    assert [p.name for p in find_measurements(tmp_path)] == ["B.CSV", "a.brdf", "sub.csv", "table.binary"]
    assert [read_samples(p).n_channels for p in find_measurements(tmp_path)[:2]] == [2, 3]
    with pytest.raises(DataError, match="is a folder"):
        read_samples(tmp_path / "sub.csv")
    with pytest.raises(MerlError, match="not a MERL file"):
        read_samples(tmp_path / "table.binary")
    # the hook: registering a suffix is all a new format takes
    seen = []

    def fake(path: Path):
        seen.append(path)
        return read_cornell(tmp_path / "a.brdf")

    monkeypatch.setitem(READERS, ".binary", fake)
    assert [p.name for p in find_measurements(tmp_path)] == ["B.CSV", "a.brdf", "sub.csv", "table.binary"]
    assert read_samples(str(tmp_path / "table.binary")).n_samples == 2 and seen == [tmp_path / "table.binary"]
    monkeypatch.setitem(READERS, ".gz", fake)
    monkeypatch.setitem(READERS, ".brdf.gz", read_cornell)
    assert readers.reader_for("x.brdf.gz") is read_cornell                    # the longest suffix wins
    assert readers.reader_for(".brdf") is None                                # a hidden name, not a suffix
    with pytest.raises(DataError, match="no such folder"):
        find_measurements(tmp_path / "nope")
    with pytest.raises(DataError, match="not a folder"):
        find_measurements(tmp_path / "a.brdf")


def test_a_batch_is_read_into_its_stacked_arrays_without_the_one_that_fails():
    """Measurements of one layout are read straight into one array per index set; one that
    cannot be read is told to on_error and its row left out, the others in order."""
    from types import SimpleNamespace

    from brdfcl.device.cellsets import read_stacked

    def fake(k):
        def values_at(indices, outs):
            if k == 1:
                raise OSError("truncated")
            for idx, out in zip(indices, outs):
                out[:] = k * 1000 + np.asarray(idx)[None, :] + np.arange(3)[:, None] * 0.5
        return SimpleNamespace(n_channels=3, values_at=values_at, name=f"m{k}")

    ms = [fake(k) for k in range(4)]
    idx = [np.arange(10), np.arange(0, 10, 3)]
    told = []
    kept, stacked = read_stacked(ms, idx, np.float32, lambda m, e: told.append((m.name, str(e))))
    assert kept == [0, 2, 3] and told == [("m1", "truncated")]
    assert [s.shape for s in stacked] == [(3, 3, 10), (3, 3, 4)]
    for row, k in enumerate(kept):
        np.testing.assert_array_equal(stacked[1][row, 2], k * 1000 + idx[1] + 1.0)
