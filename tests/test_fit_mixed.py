"""brdfcl fit-all on a folder mixing MERL tables, Cornell spectral samples and a bad CSV, as a
user runs it: every readable file fitted, the bad one skipped in one line, resumable, and
--rgb fitting the spectra as linear sRGB."""
import csv
import json
import shutil
import subprocess
import sys

import pytest

CLI = [sys.executable, "-m", "brdfcl.app.cli"]
# One reflection form for the 31-band spectra: compiling a 31-channel program costs about a minute
# a form on a cold cache, and the choice among the default forms is tested on tables
# (test_forms.py); the cluster test fits two (TWO), to check that scattered samples fit every
# form in full.
FORMS = ("--forms", "gtr:dielectric")
TWO_FORMS = ("gtr:dielectric", "abc:schlick")
TWO = ("--forms", ",".join(TWO_FORMS))


@pytest.fixture(scope="module")
def mixed(tmp_path_factory, demo_db, krylon):
    d = tmp_path_factory.mktemp("mixed")
    shutil.copy(krylon.path, d / "krylon_blue.brdf")
    shutil.copy(demo_db / "synth-fabric.binary", d)
    (d / "bad.csv").write_text("theta_i,phi_i,theta_o,phi_o,R,G\n10,0,20,180,0.1\n")
    return d


def _run(*args, forms=FORMS):
    return subprocess.run([*CLI, "fit-all", *map(str, args), *forms, "--quiet", "--no-report"],
                          capture_output=True, text=True)


@pytest.mark.slow
def test_a_folder_mixing_formats(mixed, tmp_path):
    out = tmp_path / "o"
    r = _run(mixed, "--out", out)
    assert r.returncode == 1, r.stderr          # a file was skipped
    assert "fitted 2 materials" in r.stdout and "1 skipped" in r.stdout
    skipped = [ln for ln in r.stderr.splitlines() if ln.startswith("skipped:")]
    assert skipped == [f"skipped: {mixed / 'bad.csv'}:2: 5 columns, expected 6 as in the header"]
    k = json.loads((out / "krylon_blue.json").read_text())
    assert len(k["wavelengths_um"]) == 31 and "diffuse.rho_550nm" in k["params"] and k["success"]
    m = json.loads((out / "synth-fabric.json").read_text())
    assert m["wavelengths_um"] == [0.645, 0.526, 0.444]
    header = (out / "summary.csv").read_text().splitlines()[0].split(",")
    assert "diffuse.rho_r" in header and "diffuse.rho_700nm" in header
    again = _run(mixed, "--out", out)
    assert "2 already done" in again.stdout


@pytest.mark.slow
def test_rgb_fits_the_spectra_as_srgb_and_exports_them(mixed, tmp_path):
    pytest.importorskip("colour")
    out = tmp_path / "o"
    r = _run(mixed, "--out", out, "--rgb", "--export-merl")
    assert "fitted 2 materials" in r.stdout, r.stderr
    k = json.loads((out / "krylon_blue.json").read_text())
    assert k["wavelengths_um"] == [0.645, 0.526, 0.444] and k["options"]["rgb"] is True
    assert (out / "krylon_blue.binary").stat().st_size > 0


@pytest.mark.slow
def test_spectral_fits_are_not_exported_as_merl(mixed, tmp_path):
    out = tmp_path / "o"
    r = subprocess.run([*CLI, "fit-all", str(mixed), "--out", str(out), "--export-merl", "--no-report", *FORMS],
                       capture_output=True, text=True)
    assert (out / "synth-fabric.binary").exists() and not (out / "krylon_blue.binary").exists()
    assert "krylon_blue: no merl export: it is a fit of 31 spectral channels" in r.stderr


@pytest.mark.slow
def test_analyze_takes_the_same_mixed_folder(mixed, tmp_path):
    out = tmp_path / "a"
    r = subprocess.run([*CLI, "analyze", str(mixed), "--out", str(out), "--quiet", "--no-figures",
                        "--no-report"], capture_output=True, text=True)
    assert "analysed 2 materials" in r.stdout, r.stderr
    assert f"skipped: {mixed / 'bad.csv'}:2: 5 columns, expected 6 as in the header" in r.stderr
    rows = {row["material"]: row for row in csv.DictReader((out / "analysis.csv").open())}
    assert set(rows) == {"krylon_blue", "synth-fabric"}
    k, m = rows["krylon_blue"], rows["synth-fabric"]
    assert k["gradient_test"].startswith("not run") and k["grad_cells"] == "" and float(k["law_ratio"]) > 0
    assert m["gradient_test"] == "" and m["grad_cells"] != ""
    assert (out / "synth-fabric.exr").exists() and not (out / "krylon_blue.exr").exists()


def test_two_files_of_one_material_name_give_one_result(krylon, tmp_path):
    from brdfcl.data.csvsamples import write_csv
    src = tmp_path / "in"
    src.mkdir()
    shutil.copy(krylon.path, src / "krylon_blue.brdf")
    write_csv(krylon, src / "krylon_blue.csv")
    r = _run(src, "--out", tmp_path / "o", "--model", "diffuse+ggx")     # the name, not the fit
    assert "fitted 1 material" in r.stdout and "1 skipped" in r.stdout, r.stderr
    assert (f"skipped: {src / 'krylon_blue.csv'}: material name 'krylon_blue' already taken by "
            f"{src / 'krylon_blue.brdf'} (one result per name; rename one file to fit both)") in r.stderr


@pytest.mark.slow
@pytest.mark.parametrize("rgb", [False, True])
def test_sample_fits_get_report_pages(krylon, tmp_path, rgb):
    if rgb:
        pytest.importorskip("colour")
    src = tmp_path / "in"
    src.mkdir()
    shutil.copy(krylon.path, src / "krylon_blue.brdf")
    r = subprocess.run([*CLI, "fit-all", str(src), "--out", str(tmp_path / "o"), "--quiet", *FORMS, *(["--rgb"] * rgb)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "o" / "report" / "krylon_blue" / "krylon_blue-in-plane-slices.png").stat().st_size > 10000
    assert "Measured samples and the fit in the plane of incidence" in (
        tmp_path / "o" / "report" / "krylon_blue.html").read_text()


@pytest.mark.slow
def test_a_cluster_takes_the_mixed_folder(mixed, tmp_path):
    """One path for every format: a Dask cluster fits tables and spectral samples alike, as in
    this process."""
    pytest.importorskip("distributed")
    r = _run(mixed, "--out", tmp_path / "here", forms=TWO)
    c = _run(mixed, "--out", tmp_path / "cluster", "--workers", "2", forms=TWO)
    assert "fitted 2 materials" in c.stdout and "1 skipped" in c.stdout, c.stderr
    for name in ("krylon_blue", "synth-fabric"):
        a, b = (json.loads((tmp_path / d / f"{name}.json").read_text()) for d in ("here", "cluster"))
        assert a["errors"]["rmse_log"] == b["errors"]["rmse_log"] and a["form"] == b["form"], name
    assert r.returncode == c.returncode == 1                       # bad.csv skipped in both
    # scattered samples have no preview cells: every form fitted in full
    k = json.loads((tmp_path / "here" / "krylon_blue.json").read_text())
    assert len(k["wavelengths_um"]) == 31 and set(k["form_errors"]) == set(TWO_FORMS)
    assert all("rmse_log" in v for v in k["form_errors"].values())


@pytest.mark.slow
def test_the_lobe_comparison_takes_the_mixed_folder(mixed, tmp_path):
    """--select-lobes chooses each material's form and compares its lobes, spectral ones too."""
    s = _run(mixed, "--out", tmp_path / "selected", "--select-lobes")
    assert "fitted 2 materials" in s.stdout, s.stderr
    k = json.loads((tmp_path / "selected" / "krylon_blue.json").read_text())
    assert k["selected_by"] == "lobe comparison" and k["verdict"] == "none" and k["form"] == FORMS[1]
    assert len(k["wavelengths_um"]) == 31


@pytest.mark.slow
def test_the_lobe_comparison_takes_the_mixed_folder_in_rgb(mixed, tmp_path):
    pytest.importorskip("colour")
    g = _run(mixed, "--out", tmp_path / "rgb", "--select-lobes", "--rgb")
    assert "fitted 2 materials" in g.stdout, g.stderr
    assert len(json.loads((tmp_path / "rgb" / "krylon_blue.json").read_text())["wavelengths_um"]) == 3
