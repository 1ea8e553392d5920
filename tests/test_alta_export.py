"""``brdfcl export NAME.json --alta OUT [--at FILE]``: a fit written as an ALTA data file at the
points of its measurement, of another ALTA file or on the default grid, with the values of the
model's float64 reference; read back by brdfcl's own reader."""
from __future__ import annotations

import numpy as np
import pytest

from brdfcl.app.cli import main
from brdfcl.data.alta import AltaTable, read_alta, read_rows
from brdfcl.data.alta_write import alta_text
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.report.export.alta import write_alta_fit
from brdfcl.report.export.fitfile import fit_document
from brdfcl.report.writers import export_writers

SPEC = "diffuse+ggx"


def fit(lambdas=None, source=None):
    """A fit document of known parameters (as NAME.json), its model and parameter vector."""
    model = Model(SPEC, lambdas=lambdas) if lambdas else Model(SPEC)
    values = np.array([{"alpha": 0.2}.get(s.name.split(".")[-1], 0.3 if "rho" in s.name else s.param.default)
                       for s in model.slots])
    doc = fit_document(model, values, "felt")
    if source is not None:
        doc["source"] = str(source)
    return doc, model, values


def expected(model, values, wi, wo):
    """The model's reference at direction pairs (n, 3), (C, n)."""
    return model.reference(Cells.from_directions(wi, wo), values, jacobian=False)


def cos_th_file(path, theta_h):
    x = np.cos(theta_h)[:, None]
    path.write_text(alta_text("COS_TH", x, np.full((x.size, 3), 0.1), "RGB_COLOR", ["a measured slice"]))
    return path


def test_at_its_measurement_s_points_in_its_parametrisation(tmp_path):
    theta_h = np.radians([0.0, 20.0, 40.0, 60.0, 80.0])
    source = cos_th_file(tmp_path / "felt.alta", theta_h)
    doc, model, values = fit(source=source)
    out, points = write_alta_fit(tmp_path / "felt-fit.alta", doc)
    assert points.path == str(source)
    rows = read_rows(out)
    assert (rows.param_in, rows.param_out) == ("COS_TH", "RGB_COLOR")
    np.testing.assert_array_equal(rows.x, read_rows(source).x)
    h = np.column_stack([np.sin(theta_h), np.zeros(5), np.cos(theta_h)])     # COS_TH: wi = wo = h
    np.testing.assert_allclose(rows.values, expected(model, values, h, h).T, rtol=1e-15)
    back = read_alta(out)                                                 # the reader's directions, too
    np.testing.assert_allclose(back.values, expected(model, values, back.wi, back.wo).T, rtol=1e-15)


def test_at_another_file_s_points_and_outputs(tmp_path):
    theta_l, theta_v, dphi = np.radians([[15, 15, 30, 60], [15, 40, 30, 89], [0, 180, 90, 45]])
    x = np.column_stack([theta_l, theta_v * np.cos(dphi), theta_v * np.sin(dphi)])
    at = tmp_path / "retro.dat"
    at.write_text("#DIM 3 1\n#VS 0\n#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI\n"
                  + "".join(" ".join(repr(float(v)) for v in (*r, 0.5)) + "\n" for r in x))
    doc, model, values = fit()
    out, _ = write_alta_fit(tmp_path / "rgb-at-retro.alta", doc, at=at)
    rows = read_rows(out)
    assert (rows.param_in, rows.param_out) == ("ISOTROPIC_TL_TV_PROJ_DPHI", "INV_STERADIAN")
    np.testing.assert_array_equal(rows.x, x)
    view = np.column_stack([np.sin(theta_v) * np.cos(dphi), np.sin(theta_v) * np.sin(dphi), np.cos(theta_v)])
    light = np.column_stack([np.sin(theta_l), np.zeros(4), np.cos(theta_l)])
    rgb = expected(model, values, view, light)
    np.testing.assert_allclose(rows.values[:, 0], rgb.mean(axis=0), rtol=1e-14)   # one output: the mean
    # a one-channel fit at an RGB file: the one value in R, G and B
    doc1, model1, values1 = fit(lambdas=(0.55,))
    rgb_file = cos_th_file(tmp_path / "rgb.alta", np.radians([5.0, 50.0]))
    out1, _ = write_alta_fit(tmp_path / "grey.alta", doc1, at=rgb_file)
    v = read_rows(out1).values
    assert read_rows(out1).param_out == "RGB_COLOR" and np.all(v == v[:, :1]) and np.all(v > 0)


def test_without_a_readable_source_on_the_default_grid(tmp_path):
    doc, model, values = fit(source=tmp_path / "gone.alta")
    out, points = write_alta_fit(tmp_path / "grid.alta", doc)
    assert points.path is None and "RUSIN_TH_TD_PD grid" in points.origin
    table = read_alta(out)
    assert isinstance(table, AltaTable) and table.layout.shape == (30, 30, 60)    # read back as a table
    cells = table.layout.select(None)
    np.testing.assert_allclose(table.values[:, cells],
                               expected(model, values, table.layout.wi[cells], table.layout.wo[cells]), rtol=1e-12)
    below = np.setdiff1d(np.arange(table.values.shape[1]), cells)
    assert below.size and np.isnan(table.values[:, below]).all()               # no BRDF: left out
    assert len(read_rows(out).x) == cells.size < 30 * 30 * 60


def test_scattered_samples_as_cartesian_pairs(tmp_path):
    csv = tmp_path / "gonio.csv"
    csv.write_text("theta_i,phi_i,theta_o,phi_o,R,G,B\n30,0,30,180,0.8,0.6,0.4\n10,0,60,90,0.1,0.1,0.1\n")
    doc, model, values = fit(source=csv)
    out, _ = write_alta_fit(tmp_path / "gonio-fit.alta", doc)
    rows = read_rows(out)
    assert rows.param_in == "CARTESIAN" and rows.x.shape == (2, 6)
    wi, wo = rows.x[:, :3], rows.x[:, 3:]
    np.testing.assert_allclose(wi[0], [np.sin(np.pi / 6), 0, np.cos(np.pi / 6)], atol=1e-15)
    np.testing.assert_allclose(rows.values, expected(model, values, wi, wo).T, rtol=1e-15)


def test_the_export_command(tmp_path, capsys):
    import json
    source = cos_th_file(tmp_path / "felt.alta", np.radians([10.0, 30.0]))
    doc, _, _ = fit(source=source)
    (tmp_path / "felt.json").write_text(json.dumps(doc))
    assert main(["export", str(tmp_path / "felt.json"), "--alta", str(tmp_path / "out.alta")]) == 0
    said = capsys.readouterr().out
    assert f"at the 2 points of the measurement {source}" in said and f"wrote {tmp_path / 'out.alta'}" in said
    assert read_rows(tmp_path / "out.alta").param_in == "COS_TH"
    for argv, problem in [(["--at", str(source)], "--at FILE gives the points of --alta PATH"),
                          (["--alta", str(source)], "would overwrite the file whose points"),
                          (["--alta", str(tmp_path / "x.alta"), "--at", str(tmp_path / "felt.json")], "felt.json")]:
        assert main(["export", str(tmp_path / "felt.json"), *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert problem in err and "\n" not in err, err
    assert "alta" in export_writers()


def test_a_spectral_fit_needs_an_alta_file_s_outputs(tmp_path):
    doc, _, _ = fit(lambdas=(0.45, 0.5, 0.55, 0.6, 0.65))
    with pytest.raises(ValueError, match="a fit of 5 spectral channels"):
        write_alta_fit(tmp_path / "x.alta", doc)
    at = tmp_path / "one.alta"
    at.write_text(alta_text("ISOTROPIC_TV_TL_DPHI", [[0.2, 0.3, 3.0]], [[1.0]], "INV_STERADIAN"))
    out, _ = write_alta_fit(tmp_path / "x.alta", doc, at=at)
    assert read_rows(out).values.shape == (1, 1)
