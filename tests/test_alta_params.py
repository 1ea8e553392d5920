"""ALTA's parametrisations (brdfcl.data.alta_params) as the reader places them, the writer's
round trip, and a malformed ALTA file as one line.

The files are written here from known directions, and the directions brdfcl derives are checked
against ones computed in the test from ALTA's stated conventions (COS_TH: theta_d = 0, so wi = wo
= h; ISOTROPIC_TL_TV_PROJ_DPHI: the light at phi = 0, the view at theta_v = |(x, y)|, azimuth
atan2(y, x))."""
from __future__ import annotations

import numpy as np
import pytest

from brdfcl.data.alta import read_alta, read_rows
from brdfcl.data.alta_params import PARAMS, directions
from brdfcl.data.alta_write import alta_text
from brdfcl.data.errors import DataError
from brdfcl.data.readers import read_measurement
from brdfcl.data.samples import Samples


def spherical(theta, phi):
    """Unit vectors written out from spherical angles (the test's own, not brdfcl's)."""
    return np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


def exact(v) -> str:
    """A float written so that it reads back the same."""
    return repr(float(v))


def as_pairs(s: Samples) -> np.ndarray:
    """Each sample's (wi, wo) as one 6-vector."""
    return np.hstack([s.wi, s.wo])


def test_a_cos_th_slice_is_backscatter_at_theta_h(tmp_path):
    theta_h = np.radians([0.0, 10.0, 35.0, 60.0, 85.0])
    rgb = np.column_stack([np.linspace(0.1, 0.5, 5), np.linspace(0.2, 0.6, 5), np.linspace(0.3, 0.7, 5)])
    p = tmp_path / "slice.alta"
    p.write_text("# a 1-D slice\n#DIM 1 3\n#PARAM_IN  COS_TH\n#PARAM_OUT RGB_COLOR\n"
                 + "".join("\t".join(map(exact, (np.cos(t), *v))) + "\t\n" for t, v in zip(theta_h, rgb)))
    s = read_measurement(p)
    assert isinstance(s, Samples) and s.n_samples == 5 and [c.name for c in s.channels] == ["R", "G", "B"]
    h = np.column_stack([np.sin(theta_h), np.zeros(5), np.cos(theta_h)])      # theta_d = 0: wi = wo = h
    np.testing.assert_allclose(s.wi, h, atol=1e-12)
    np.testing.assert_allclose(s.wo, h, atol=1e-12)
    np.testing.assert_array_equal(s.values, rgb)
    theta_h_read, theta_d, _ = s.isotropic()
    np.testing.assert_allclose(theta_h_read, theta_h, atol=1e-7)
    np.testing.assert_allclose(theta_d, 0.0, atol=1e-7)


def test_projected_dphi_places_the_view_around_the_light(tmp_path):
    theta_l = np.radians([15.0, 15.0, 30.0, 30.0, 60.0, 60.0])
    theta_v = np.radians([15.0, 15.0, 45.0, 20.0, 70.0, 5.0])
    dphi = np.radians([0.0, 180.0, 90.0, -120.0, 10.0, 200.0])
    x, y = theta_v * np.cos(dphi), theta_v * np.sin(dphi)
    brdf = np.array([70.0, 0.8, 0.05, 0.04, 0.3, 0.2])
    p = tmp_path / "retro.dat"                   # as ALTA's retro data: .dat, no #PARAM_OUT, #VS 0
    p.write_text("#SAMPLE \"tape\"\n#DIM 3 1\n#VS 0\n#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI\n"
                 + "".join(" ".join(map(exact, row)) + "\n" for row in zip(theta_l, x, y, brdf)))
    s = read_measurement(p)
    assert isinstance(s, Samples) and s.n_samples == 6
    assert len(s.channels) == 1 and s.channels[0].wavelength_um == 0.55       # one BRDF value in 1/sr
    view = spherical(theta_v, dphi)
    light = spherical(theta_l, np.zeros(6))
    np.testing.assert_allclose(as_pairs(s), np.hstack([view, light]), atol=1e-12)
    np.testing.assert_array_equal(s.values[:, 0], brdf)
    # x = theta_l, y = 0: the retro direction (view = light); x = -theta_l: the mirror direction
    np.testing.assert_allclose(s.wi[0], s.wo[0], atol=1e-12)
    np.testing.assert_allclose(s.wi[1] + s.wo[1], [0.0, 0.0, 2 * np.cos(theta_l[1])], atol=1e-12)


RANGES = {          # coordinates whose two directions lie above the horizon
    "COS_TH": [(0.2, 1.0)],
    "COS_TH_TD": [(0.85, 1.0), (0.85, 1.0)],
    "RUSIN_TH_TD": [(0.0, 0.6), (0.0, 0.6)],
    "RUSIN_TH_TD_PD": [(0.0, 0.6), (0.0, 0.6), (0.0, 2 * np.pi)],
    "RUSIN_TH_PH_TD_PD": [(0.0, 0.6), (-np.pi, np.pi), (0.0, 0.6), (0.0, 2 * np.pi)],
    "ISOTROPIC_TV_TL_DPHI": [(0.0, 1.4), (0.0, 1.4), (-np.pi, np.pi)],
    "ISOTROPIC_TL_TV_PROJ_DPHI": [(0.0, 1.4), (-1.0, 1.0), (-1.0, 1.0)],
    "SPHERICAL_TL_PL_TV_PV": [(0.0, 1.4), (-np.pi, np.pi), (0.0, 1.4), (-np.pi, np.pi)],
    "CARTESIAN": [(-0.6, 0.6), (-0.6, 0.6), (0.3, 1.0)] * 2,
}


def test_every_parametrisation_has_a_range_here():
    assert set(RANGES) == set(PARAMS)


@pytest.mark.parametrize("param", sorted(PARAMS))
@pytest.mark.parametrize("output, n_out", [("RGB_COLOR", 3), ("INV_STERADIAN", 1)])
def test_the_writer_round_trips_values_and_directions(tmp_path, param, output, n_out):
    rng = np.random.default_rng(len(param) * 10 + n_out)
    x = np.column_stack([rng.uniform(lo, hi, 40) for lo, hi in RANGES[param]])
    values = rng.uniform(0.01, 5.0, (40, n_out))
    p = tmp_path / "fit.alta"
    p.write_text(alta_text(param, x, values, output, ["brdfcl round trip", "second\nline"]))
    rows = read_rows(p)
    assert (rows.param_in, rows.param_out) == (param, output)
    np.testing.assert_array_equal(rows.x, x)                      # 17 digits: the same float64
    np.testing.assert_array_equal(rows.values, values)
    s = read_alta(p)
    assert isinstance(s, Samples) and s.n_samples == 40
    wi, wo = directions(param, x)
    np.testing.assert_allclose(as_pairs(s), np.hstack([wi, wo]), atol=1e-12)
    np.testing.assert_array_equal(s.values, values)
    if param.startswith("RUSIN"):                                 # brdfcl's own angles of the pairs
        th, td, _ = s.isotropic()
        np.testing.assert_allclose(th, x[:, 0], atol=1e-7)
        np.testing.assert_allclose(td, x[:, 2 if param == "RUSIN_TH_PH_TD_PD" else 1], atol=1e-7)


def test_a_value_without_a_brdf_is_written_missing(tmp_path):
    p = tmp_path / "gaps.alta"
    p.write_text(alta_text("ISOTROPIC_TV_TL_DPHI", [[0.1, 0.2, 0.0], [0.3, 0.4, 1.0], [0.5, 0.6, 2.0]],
                           [[1.0], [np.nan], [-3.0]], "INV_STERADIAN"))
    assert read_alta(p).n_samples == 1
    assert np.isnan(read_rows(p).values[1:]).all()
    with pytest.raises(ValueError, match="ISOTROPIC_TV_TL_DPHI rows need 3 coordinates"):
        alta_text("ISOTROPIC_TV_TL_DPHI", [[0.1, 0.2]], [[1.0]], "INV_STERADIAN")


RETRO = "#DIM 3 1\n#VS 0\n#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI\n"
ROW = "0.2617993877991494  0.1745329251994329  0.0  0.98804851752\n"


@pytest.mark.parametrize("name, text, problem", [
    ("cut.dat", RETRO + ROW + "0.2617993877991494  0.17485994", ":5: 2 numbers, expected at least 4"),
    ("cut.dat", "#DIM 3 1\n#VS", "no data rows after the header"),
    ("dim.dat", RETRO.replace("#DIM 3 1", "#DIM 2 1") + ROW, "#DIM 2 1: ISOTROPIC_TL_TV_PROJ_DPHI has 3 inputs"),
    ("dim.alta", "#DIM 3\n#PARAM_IN COS_TH\n0.5 1 1 1\n", "no #DIM line"),
    ("stark.alta", RETRO.replace("ISOTROPIC_TL_TV_PROJ_DPHI", "STARK_2D") + ROW, "#PARAM_IN STARK_2D: brdfcl reads"),
    ("rgb.alta", "#DIM 1 3\n#PARAM_IN COS_TH\n0.5 1 1 1\n", "no #PARAM_OUT and 3 outputs"),
    ("binary.alta", "#DIM 1 1\n#PARAM_IN COS_TH\n#FORMAT binary\n0.5 1\n", "#FORMAT binary"),
    ("notes.dat", "temperature log\n20.5 21.0\n", "not an ALTA data file (no #DIM header line)"),
])
def test_a_malformed_alta_file_is_one_line(tmp_path, name, text, problem):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(DataError) as e:
        read_measurement(p)
    assert problem in str(e.value) and str(p) in str(e.value) and "\n" not in str(e.value)


def test_a_folder_lists_only_the_dat_files_that_are_altas(tmp_path):
    from brdfcl.data.readers import find_measurements
    (tmp_path / "notes.dat").write_text("temperature log\n20.5 21.0\n")
    (tmp_path / "tape.dat").write_text(RETRO + ROW)
    (tmp_path / "empty.dat").write_bytes(b"")
    assert [p.name for p in find_measurements(tmp_path)] == ["tape.dat"]
