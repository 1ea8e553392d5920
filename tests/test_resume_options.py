"""Input data is read-only; results record the options that made them, and resuming respects them."""
import csv
import hashlib
import json
import os
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from brdfcl.app.run import InputOverwriteError, Models, ResultsDiffer, check_output_not_input, fit_all
from brdfcl.data.merl import read_merl
from brdfcl.optim.fit import FitOptions
from brdfcl.report.output import NOT_RESULT_OPTIONS, option_difference, recorded_options, resume_state

CLI = [sys.executable, "-m", "brdfcl.app.cli"]
MODEL = "diffuse+ggx"
NAME = "synth-mirror"


def cli(*args, **kw):
    return subprocess.run(CLI + [str(a) for a in args], capture_output=True, text=True, **kw)


def snapshot(folder):
    """Every file under folder -> (sha1 of its bytes, mtime_ns); a symlink: its target, its own mtime.
    Hashes, not bytes: a failing comparison must not print whole MERL files."""
    out = {}
    for root, _, files in os.walk(folder):
        for f in files:
            p = os.path.join(root, f)
            st = os.lstat(p)
            what = hashlib.sha1(Path(p).read_bytes()).hexdigest() if os.path.isfile(p) else os.readlink(p)
            out[p] = (what, st.st_mtime_ns)
    return out


def one_error_line(r, *words):
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("brdfcl: error: "), r.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.fixture()
def db(demo_db, tmp_path):
    """A database folder of two real files (copies, so that overwriting them would show)."""
    d = tmp_path / "db"
    d.mkdir()
    for n in (NAME, "synth-fabric"):
        (d / f"{n}.binary").write_bytes((demo_db / f"{n}.binary").read_bytes())
    return d


@pytest.mark.slow
def test_export_into_the_input_folder_is_refused(db, tmp_path):
    before = snapshot(tmp_path)
    r = cli("fit-all", db, "--out", db, "--export-merl", "--model", MODEL, "--quiet")
    one_error_line(r, "is the input folder", "read-only")
    r = cli("fit-all", db, "--out", db / "fits", "--model", MODEL, "--quiet")
    one_error_line(r, "is inside the input folder")
    r = cli("fit-all", db, "--out", tmp_path, "--model", MODEL, "--quiet")
    one_error_line(r, "holds the input folder")
    assert snapshot(tmp_path) == before                   # nothing written, created or touched
    # relative paths and a link to the input folder resolve to it
    (tmp_path / "dblink").symlink_to(db)
    before = snapshot(tmp_path)
    r = cli("fit-all", "db", "--out", "./sub/../db/", "--export-merl", "--model", MODEL, cwd=tmp_path)
    one_error_line(r, "is the input folder")
    r = cli("fit-all", "db", "--out", "dblink/fits", "--model", MODEL, cwd=tmp_path)
    one_error_line(r, "is inside the input folder")
    r = cli("fit-all", "dblink", "--out", "db", "--export-merl", "--model", MODEL, cwd=tmp_path)
    one_error_line(r, "input folder")
    # --select-lobes goes the same way
    r = cli("fit-all", db, "--out", db, "--export-merl", "--select-lobes", "--quiet")
    one_error_line(r, "is the input folder")
    assert snapshot(tmp_path) == before


def test_links_to_files_elsewhere_protect_the_files(db, tmp_path):
    """A database folder of symlinks: --out being the folder they point to is refused."""
    links = tmp_path / "links"
    links.mkdir()
    for p in db.glob("*.binary"):
        (links / p.name).symlink_to(p)
    before = snapshot(tmp_path)
    r = cli("fit-all", links, "--out", db, "--export-merl", "--model", MODEL, "--quiet")
    line = one_error_line(r, "holds the input file")
    assert str(db) in line
    assert snapshot(tmp_path) == before


def test_python_api_refuses_every_path_into_the_input(db, tmp_path):
    f = db / f"{NAME}.binary"
    before = snapshot(tmp_path)
    with pytest.raises(InputOverwriteError, match="holds the input file"):
        fit_all(f, db, model=MODEL, export=True)                          # a single file
    with pytest.raises(InputOverwriteError, match="is the input file"):
        fit_all([f], f, model=MODEL)                                      # a list of files
    with pytest.raises(InputOverwriteError, match="holds the input file"):
        fit_all([str(f)], tmp_path, model=MODEL, export=True)
    with pytest.raises(InputOverwriteError, match="is inside the input folder"):
        fit_all(db, db / "x" / "y", model=MODEL, select_lobes=True, export=True)
    with pytest.raises(InputOverwriteError, match="is the input folder"):    # the Dask path: before the client
        fit_all(db, db, model=MODEL, client=object(), export=True)
    with pytest.raises(InputOverwriteError, match="inside the input folder"):   # what analyze calls
        check_output_not_input(db, db / "analysis")
    assert snapshot(tmp_path) == before
    check_output_not_input(db, tmp_path / "out")                          # beside the input: fine
    check_output_not_input(f, db / "fits")                                # a file's folder is not input


def test_options_are_recorded_from_fit_options(db, tmp_path):
    out = tmp_path / "out"
    rep = fit_all([db / f"{NAME}.binary"], out, model=MODEL, seed=3, cutoff_deg=70.0,
                  fixed={"ct.F0_r": 0.9})
    assert rep.ok
    doc = json.loads((out / f"{NAME}.json").read_text())
    o = doc["options"]
    every = {f.name for f in fields(FitOptions)}
    assert every - NOT_RESULT_OPTIONS <= set(o)                          # new fields recorded automatically
    assert not (NOT_RESULT_OPTIONS & set(o))
    assert o["seed"] == 3 and o["cutoff_deg"] == 70.0 and o["fixed"] == {"ct.F0_r": 0.9}
    assert o["model"] == "diffuse+ggx:smith:schlick" and o["real"] == "float" and o["lm"]["max_iter"] == 60
    assert o["select_lobes"] is False and o["export"] is False and o["brdfcl_version"]
    (row,) = csv.DictReader(open(out / "summary.csv"))
    assert row["seed"] == "3" and row["cutoff_deg"] == "70.0" and row["fixed"] == "ct.F0_r=0.9"
    assert row["real"] == "float" and len(row["options"]) == 10 and row["ct.alpha"]
    # options that do not change the result, and exporting, are not compared
    a = recorded_options(FitOptions(model=MODEL))
    assert option_difference(a, recorded_options(FitOptions(model=MODEL, device="0"))) is None
    assert option_difference({**a, "export": True}, a) is None
    assert option_difference(a, recorded_options(FitOptions(model=MODEL), select_lobes=True))[0] == "select_lobes"
    # a --select-lobes run does not take a plain fit for its own
    assert resume_state(out, NAME, Models(FitOptions(model=MODEL, seed=3, cutoff_deg=70.0, fixed={"ct.F0_r": 0.9}),
                                          select_lobes=True).options)[0] == "differs"


@pytest.mark.slow
def test_resume_checks_the_options(db, tmp_path):
    out = tmp_path / "out"
    base = ["fit-all", db, "--out", out, "--model", MODEL, "--quiet"]
    r = cli(*base)
    assert r.returncode == 0 and "fitted 2 materials" in r.stdout, r.stderr
    before = snapshot(out)
    for extra, option, flag in [(["--seed", "1"], "seed", "--seed"),
                                (["--cutoff", "60"], "cutoff_deg", "--cutoff"),
                                (["--double"], "real", "--double"),
                                (["--fix", "ct.F0_r=0.5"], "fixed", "--fix"),
                                (["--ct-peak"], "ct_peak", "--ct-peak"),
                                (["--max-iter", "20"], "lm.max_iter", "--max-iter")]:
        line = one_error_line(cli(*base, *extra), option, f" ({flag}) is ", "there", "(and 1 more of the 2 materials)",
                              "to proceed, give another output folder (--out), or add --overwrite to refit")
        assert f"{NAME}.json" in line or "synth-fabric.json" in line
        assert "overwrite=True" not in line                         # the Python API's words, not the CLI's
    line = one_error_line(cli("fit-all", db, "--out", out, "--model", "diffuse+beckmann", "--quiet"),
                          "model (--model)", "diffuse+ggx", "diffuse+beckmann")
    assert snapshot(out) == before                                        # refused before any work
    r = cli(*base)                                                        # the same options: reused
    assert r.returncode == 0 and "2 already done" in r.stdout and "fitted 0 materials" in r.stdout
    assert {k: v for k, v in snapshot(out).items() if k.endswith(".json")} == \
        {k: v for k, v in before.items() if k.endswith(".json")}
    r = cli(*base, "--seed", "1", "--overwrite")                          # --overwrite refits
    assert r.returncode == 0 and "fitted 2 materials" in r.stdout and "0 already done" in r.stdout, r.stderr
    doc = json.loads((out / f"{NAME}.json").read_text())
    assert doc["options"]["seed"] == 1 and doc["success"]
    rows = list(csv.DictReader(open(out / "summary.csv")))
    assert [row["seed"] for row in rows] == ["1", "1"]
    r = cli(*base, "--seed", "1")
    assert r.returncode == 0 and "2 already done" in r.stdout


def test_results_of_an_older_brdfcl_count_as_different(db, tmp_path):
    out = tmp_path / "out"
    paths = [db / f"{NAME}.binary"]
    fit_all(paths, out, model=MODEL)
    p = out / f"{NAME}.json"
    doc = json.loads(p.read_text())
    del doc["options"]
    p.write_text(json.dumps(doc))
    with pytest.raises(ResultsDiffer, match="older brdfcl") as e:
        fit_all(paths, out, model=MODEL)
    assert str(e.value).endswith("; to proceed, pass another out, or overwrite=True to refit and replace those "
                                 "results") and "--" not in str(e.value)      # the Python API's words
    assert "options" not in json.loads(p.read_text())
    r = cli("fit-all", db, "--out", out, "--model", MODEL)
    one_error_line(r, "older brdfcl", "add --overwrite")
    said: list[str] = []
    rep = fit_all(paths, out, model=MODEL, overwrite=True, log=said.append)
    assert len(rep.results) == 1 and "options" in json.loads(p.read_text())
    assert "overwrite: refitting 1 result made with other options" in said
    fit_all(paths, out, model=MODEL, log=said.append)
    assert f"resuming: 1 material already finished in {out}" in said


def test_the_python_api_names_options_not_flags(db, tmp_path):
    out = tmp_path / "out"
    fit_all([db / f"{NAME}.binary"], out, model=MODEL, global_method="none")
    with pytest.raises(ResultsDiffer) as e:
        fit_all([db / f"{NAME}.binary"], out, model=MODEL, global_method="lds")
    assert "was made with other options: global_method is \"none\" there, \"lds\" now; to proceed, pass " \
           "another out, or overwrite=True" in str(e.value)
    from brdfcl.app.resume import OPTION_FLAGS
    assert "global_method (--global) is" in e.value.message(OPTION_FLAGS, "go on")


@pytest.mark.slow
def test_missing_export_is_written_without_refitting(db, tmp_path):
    out = tmp_path / "out"
    base = ["fit-all", db, "--out", out, "--model", MODEL, "--quiet"]
    assert cli(*base).returncode == 0
    assert not list(out.glob("*.binary"))
    before = snapshot(out)
    r = cli(*base, "--export-merl")
    assert r.returncode == 0 and "2 already done" in r.stdout and "fitted 0 materials" in r.stdout, r.stderr
    for n in (NAME, "synth-fabric"):                                     # fits untouched, exports written
        assert snapshot(out)[str(out / f"{n}.json")] == before[str(out / f"{n}.json")]
        assert (out / f"{n}.binary").stat().st_size > 0
    exported, original = read_merl(out / f"{NAME}.binary"), read_merl(db / f"{NAME}.binary")
    ok = exported.valid & original.valid
    assert np.median(np.abs(exported.brdf()[:, ok] / original.brdf()[:, ok] - 1)) < 0.01
    after = snapshot(out)
    r = cli(*base)                                                        # without --export-merl: reused
    assert r.returncode == 0 and "2 already done" in r.stdout
    assert {k: v for k, v in snapshot(out).items() if not k.endswith("summary.csv")} == \
        {k: v for k, v in after.items() if not k.endswith("summary.csv")}
    # with --overwrite and no export, a refitted material's earlier export is removed, not left stale
    r = cli(*base, "--seed", "2", "--overwrite")
    assert r.returncode == 0 and not list(out.glob("*.binary")), r.stderr
