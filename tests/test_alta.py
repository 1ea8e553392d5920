"""ALTA's text data files (brdfcl.data.alta): a table on a Rusinkiewicz grid, or scattered samples,
read as every other measurement is and fitted, analysed, reported and spread over a cluster with
no code of their own beyond the reader."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from brdfcl.data.alta import AltaTable, GridLayout, read_alta
from brdfcl.data.errors import DataError
from brdfcl.data.geometry import TABLE, bin_centres, table_geometry, table_values
from brdfcl.data.merl import read_merl
from brdfcl.data.readers import read_measurement
from brdfcl.data.samples import Samples
from brdfcl.optim.fit import FitOptions, Fitter

HEAD = "#DIM 3 3\n#PARAM_IN RUSIN_TH_TD_PD\n#PARAM_OUT RGB_COLOR\n# exported from a MERL table\n"


def write_grid(path, table, step=(2, 2, 2)):
    """A MERL table as ALTA exports it (RUSIN_TH_TD_PD at the bin centres, missing cells -1), on
    every step-th bin of each axis."""
    th, td, pd = bin_centres()
    i, j, k = (np.arange(0, n, s) for n, s in zip((90, 90, 180), step))
    b = table.brdf().reshape(3, 90, 90, 180)[:, i][:, :, j][:, :, :, k]
    TH, TD, PD = np.meshgrid(th[i], td[j], pd[k], indexing="ij")
    rows = np.column_stack([TH.ravel(), TD.ravel(), PD.ravel(), np.nan_to_num(b.reshape(3, -1), nan=-1.0).T])
    with open(path, "w") as f:
        f.write(HEAD)
        np.savetxt(f, rows, fmt="%.10g")
    return path


def test_a_grid_is_a_table_with_the_merl_cells_values(demo_db, tmp_path):
    table = read_merl(demo_db / "synth-smooth-plastic.binary")
    m = read_measurement(write_grid(tmp_path / "plastic.alta", table, (3, 3, 3)))
    assert isinstance(m, AltaTable) and m.layout.dense and m.layout.shape == (30, 30, 60)
    assert m.name == "plastic" and m.n_channels == 3
    # at the MERL cells the grid has, the table's own values (through the layout's lookup)
    g = table_geometry()
    on_grid = np.flatnonzero(g.above_horizon)
    i, j, k = np.unravel_index(on_grid, (90, 90, 180))
    on_grid = on_grid[(i % 3 == 0) & (j % 3 == 0) & (k % 3 == 0)][::50]
    np.testing.assert_allclose(table_values(m, on_grid), table.brdf()[:, on_grid], rtol=1e-9)
    # files on one grid share one layout (one upload for a batch of them)
    again = read_measurement(write_grid(tmp_path / "again.alta", table, (3, 3, 3)))
    assert again.layout is m.layout


def test_a_full_merl_grid_has_the_merl_measure():
    th, td, pd = bin_centres()
    grid = GridLayout(th, td, pd)
    w, ref = grid.weight, table_geometry().weight
    sel = TABLE.select(80.0)
    assert grid.select(80.0).size == sel.size and np.array_equal(grid.select(80.0), sel)
    assert w[sel].sum() == pytest.approx(ref[sel].sum(), rel=2e-3)       # edges half way between centres
    np.testing.assert_allclose(np.stack(grid.rows(sel[::997])), np.stack(TABLE.rows(sel[::997])), rtol=1e-12)
    np.testing.assert_array_equal(grid.lookup(table_geometry().wi[sel[::997]], table_geometry().wo[sel[::997]]),
                                  sel[::997])


def test_scattered_rows_are_samples(tmp_path):
    p = tmp_path / "iso.alta"
    rows = ["0.2 0.3 3.0 0.1 0.2 0.3", "0.5 0.4 1.0 0.2 0.2 0.2", "0.7 0.7 0.5 -1 0.1 0.1", "1.0 1.2 2.0 0.3 0.3 0.3"]
    p.write_text("#DIM 3 3\n#PARAM_IN ISOTROPIC_TV_TL_DPHI\n#PARAM_OUT RGB_COLOR\n#VS 0\n" + "\n".join(rows) + "\n")
    s = read_measurement(p)
    assert isinstance(s, Samples) and not s.layout.dense and s.n_samples == 3       # the missing row left out
    np.testing.assert_allclose(s.theta_o, [0.3, 0.4, 1.2])
    np.testing.assert_allclose(np.cos(s.phi_o), np.cos([3.0, 1.0, 2.0]))
    p.write_text("#DIM 3 1\n#PARAM_IN RUSIN_TH_TD_PD\n#PARAM_OUT INV_STERADIAN\n#VS 2\n0.1 0.2 0.3 0.5 0.01 0.02\n")
    s = read_alta(p)
    assert s.n_samples == 1 and s.channels[0].wavelength_um == 0.55 and s.values[0, 0] == 0.5


@pytest.mark.parametrize("text, problem", [
    ("#PARAM_IN RUSIN_TH_TD_PD\n#PARAM_OUT RGB_COLOR\n0 0 0 1 1 1\n", "no #DIM line"),
    ("#DIM 3 3\n#PARAM_IN STARK_2D\n#PARAM_OUT RGB_COLOR\n0 0 0 1 1 1\n", "#PARAM_IN STARK_2D: brdfcl reads"),
    ("#DIM 3 3\n#PARAM_IN RUSIN_TH_TD_PD\n#PARAM_OUT XYZ_COLOR\n0 0 0 1 1 1\n", "#PARAM_OUT XYZ_COLOR"),
    ("#DIM 3 1\n#PARAM_IN RUSIN_TH_TD_PD\n#PARAM_OUT RGB_COLOR\n0 0 0 1 1 1\n", "#DIM 3 1: RUSIN_TH_TD_PD has 3"),
    (HEAD + "0.1 0.2 0.3 1 1 1\n0.1 0.2 1 1\n", ":6: 4 numbers, expected at least 6"),
    (HEAD + "0.1 0.2 0.3 1 x 1\n", "not a number: 'x'"),
    (HEAD, "no data rows"),
])
def test_a_malformed_file_is_one_line(tmp_path, text, problem):
    p = tmp_path / "bad.alta"
    p.write_text(text)
    with pytest.raises(DataError) as e:
        read_measurement(p)
    assert problem in str(e.value) and str(p) in str(e.value) and "\n" not in str(e.value)


def test_a_grid_fits_as_its_merl_table_does(demo_db, tmp_path):
    table = read_merl(demo_db / "synth-smooth-plastic.binary")
    m = read_measurement(write_grid(tmp_path / "plastic.alta", table, (2, 2, 2)))
    opts = FitOptions(model="diffuse+ggx:smith:dielectric")
    (r,) = Fitter(opts).fit([m])
    truth = json.loads((demo_db / "truth.json").read_text())["materials"]["synth-smooth-plastic"]["params"]
    assert r.success and r.errors["rmse_log"] < 1e-3
    for name in ("ct.alpha", "ct.eta", "diffuse.rho_r"):
        assert r.params[name] == pytest.approx(truth[name], rel=0.02), name


@pytest.mark.slow
def test_fit_all_analyze_report_and_cluster_take_alta_files(demo_db, tmp_path):
    """The commands as a user runs them, on a folder of ALTA grids."""
    db = tmp_path / "db"
    db.mkdir()
    for name in ("synth-smooth-plastic", "synth-fabric"):
        write_grid(db / f"{name}.alta", read_merl(demo_db / f"{name}.binary"), (2, 2, 2))

    def cli(*args):
        r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", *map(str, args)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        return r
    cli("fit-all", db, "--out", tmp_path / "fits", "--quiet")
    doc = json.loads((tmp_path / "fits" / "synth-smooth-plastic.json").read_text())
    assert doc["errors"]["rmse_log"] < 1e-3
    page = (tmp_path / "fits" / "report" / "synth-smooth-plastic.html").read_text()
    assert "Lit spheres: measured | fitted | difference" in page
    assert (tmp_path / "fits" / "report" / "synth-smooth-plastic" / "synth-smooth-plastic-sphere-key.png").exists()
    cli("analyze", db, "--out", tmp_path / "an", "--quiet")
    rows = (tmp_path / "an" / "analysis.csv").read_text()
    assert "synth-smooth-plastic,none" in rows and "synth-fabric,none" in rows
    model = "diffuse+ggx:smith:dielectric"
    cli("fit-all", db, "--out", tmp_path / "here", "--model", model, "--no-report", "--quiet")
    cli("fit-all", db, "--out", tmp_path / "cluster", "--model", model, "--no-report", "--quiet", "--workers", "2")
    for name in ("synth-smooth-plastic", "synth-fabric"):
        a, b = (json.loads((tmp_path / d / f"{name}.json").read_text()) for d in ("here", "cluster"))
        assert a["errors"]["rmse_log"] == b["errors"]["rmse_log"]
