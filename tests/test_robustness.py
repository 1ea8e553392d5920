"""Bad input, interrupted runs and extreme data: clear errors, nothing lost, nothing half-written."""
import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from brdfcl.app.run import fit_all
from brdfcl.data.merl import FILE_SIZE, HEADER, N_CELLS, MerlError, read_merl, write_merl
from brdfcl.data.readers import READERS
from brdfcl.model.compose import Model, ModelError

CLI = [sys.executable, "-m", "brdfcl.app.cli"]


def cli(*args, **kw):
    return subprocess.run(CLI + [str(a) for a in args], capture_output=True, text=True, **kw)


@pytest.fixture()
def mixed_db(demo_db, tmp_path):
    """Two good materials and one of every kind of bad file."""
    d = tmp_path / "db"
    d.mkdir()
    for n in ("synth-fabric", "synth-mirror"):
        (d / f"{n}.binary").symlink_to(demo_db / f"{n}.binary")
    good = (demo_db / "synth-fabric.binary").read_bytes()
    (d / "truncated.binary").write_bytes(good[:FILE_SIZE // 2])
    (d / "zero.binary").write_bytes(b"")
    (d / "header.binary").write_bytes(np.array([1, 2, 3], "<i4").tobytes() + good[12:])
    (d / "dims.binary").write_bytes(np.array([90, 90, 90], "<i4").tobytes() + good[12:])
    (d / "text.binary").write_text("this is a text file, not a BRDF\n" * 100)
    write_merl(d / "allmissing.binary", np.full((3, N_CELLS), np.nan))
    (d / "adirectory.binary").mkdir()                       # unreadable as a file, even for root
    nan = np.frombuffer(good[12:], "<f8").copy()
    nan[::7] = np.nan
    nan[1::7] = np.inf
    (d / "nanvalues.binary").write_bytes(good[:12] + nan.tobytes())   # readable: NaN/inf are missing
    return d


@pytest.mark.slow
def test_bad_files_are_skipped_with_one_line_each(mixed_db, tmp_path):
    out = tmp_path / "out"
    r = cli("fit-all", mixed_db, "--out", out, "--model", "diffuse+ggx", "--quiet")
    assert r.returncode == 1                                 # not everything succeeded
    assert "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("skipped:")]
    assert len(lines) == 7
    for name, problem in [("truncated", "wrong size"), ("zero", "not a MERL file"), ("header", "wrong header"),
                          ("dims", "wrong header"), ("text", "wrong header"), ("allmissing", "every cell is missing"),
                          ("adirectory", "cannot read")]:
        assert any(f"{name}.binary" in ln and problem in ln for ln in lines), (name, lines)
    docs = {p.stem for p in out.glob("*.json")}
    assert docs == {"synth-fabric", "synth-mirror", "nanvalues"}
    assert "fitted 3 materials" in r.stdout and "7 skipped" in r.stdout


@pytest.mark.slow
def test_empty_folder_bad_output_bad_model(tmp_path, demo_db):
    (tmp_path / "empty").mkdir()
    r = cli("fit-all", tmp_path / "empty", "--out", tmp_path / "o")
    assert r.returncode == 2
    formats = ", ".join(sorted(READERS))
    assert f"no measurement files in this folder ({formats}; subfolders are not searched)" in r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    (tmp_path / "afile").write_text("x")
    r = cli("fit-all", demo_db, "--out", tmp_path / "afile" / "sub")
    assert r.returncode == 2 and "cannot be written" in r.stderr and str(tmp_path / "afile") in r.stderr
    r = cli("fit-all", demo_db, "--out", tmp_path / "o", "--model", "diffuse+phong")
    assert r.returncode == 2 and "unknown lobe 'phong'" in r.stderr and "ggx" in r.stderr
    r = cli("fit-all", demo_db, "--out", tmp_path / "o", "--model", "difraction")
    assert r.returncode == 2 and "unknown lobe 'difraction'; did you mean 'diffraction'?" in r.stderr
    r = cli("fit-all", demo_db, "--out", tmp_path / "o", "--fix", "ct.nope=1")
    assert r.returncode == 2 and "cannot fix 'ct.nope'" in r.stderr and "ct.alpha" in r.stderr
    r = cli("fit-all", demo_db, "--out", tmp_path / "o", "--metric", "l3")
    assert r.returncode == 2 and "invalid choice" in r.stderr
    r = cli("fit-all", demo_db, "--out", tmp_path / "o", "--debug", "--model", "ggx:vcavity:vcavity")
    assert r.returncode != 0 and "Traceback" in r.stderr          # --debug shows it
    with pytest.raises(ModelError, match="smith"):
        Model("sgd:smith")


def test_file_disappearing_during_the_run(demo_db, tmp_path):
    d = tmp_path / "db"
    d.mkdir()
    for n in ("synth-fabric", "synth-mirror", "synth-smooth-plastic"):
        (d / f"{n}.binary").write_bytes((demo_db / f"{n}.binary").read_bytes())

    def log(msg):
        if msg.startswith("batch of") and (d / "synth-smooth-plastic.binary").exists():
            (d / "synth-smooth-plastic.binary").unlink()
    rep = fit_all(d, tmp_path / "o", batch=1, model="diffuse+ggx", log=log)
    assert len(rep.results) == 2 and not rep.ok
    (path, why), = rep.skipped.items()
    assert "synth-smooth-plastic.binary" in path and "disappeared" in why


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL])
def test_interrupted_run_resumes(demo_db, tmp_path, sig):
    out = tmp_path / "out"
    args = CLI + ["fit-all", str(demo_db), "--out", str(out), "--model", "diffuse+diffraction+ggx", "--quiet",
                  "--batch", "1"]
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.time()
    while not list(out.glob("*.json")) and time.time() - t0 < 120:
        time.sleep(0.05)
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    if sig == signal.SIGINT:
        assert p.returncode == 130 and "interrupted" in err and "Traceback" not in err
    done = list(out.glob("*.json"))
    assert 1 <= len(done) < 5
    for f in done:                                         # every result complete and readable
        assert json.loads(f.read_text())["success"]
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert f"{len(done)} already done" in r.stdout
    assert len(list(out.glob("*.json"))) == 5
    assert not [p for p in out.iterdir() if ".tmp" in p.name]


@pytest.mark.parametrize("name, brdf", [
    ("black", np.zeros(3)), ("white", np.full(3, 1 / np.pi)), ("near-black", np.full(3, 1e-7))])
def test_extreme_materials_end_cleanly(tmp_path, name, brdf):
    from brdfcl.data.geometry import table_geometry
    g = table_geometry()
    t = np.where(g.above_horizon, 1.0, np.nan)[None, :] * brdf[:, None]
    write_merl(tmp_path / f"{name}.binary", t)
    rep = fit_all(tmp_path / f"{name}.binary", tmp_path / "o")
    (r,) = rep.results
    assert np.isfinite(r.loss) and all(np.isfinite(v) for v in r.errors.values())
    assert r.status and r.success
    assert all(np.isfinite(v) for v in r.params.values())
    if name == "white":
        assert r.errors["rel_rmse"] < 0.05


@pytest.mark.slow
def test_merl_reader_fuzz(tmp_path):
    """Random headers, sizes and contents: a table or a MerlError, never anything else."""
    rng = np.random.default_rng(7)
    p = tmp_path / "fuzz.binary"
    t0 = time.time()
    kinds = {"ok": 0, "error": 0}
    for _ in range(300):
        head = rng.choice([HEADER, rng.integers(-5, 200, 3).astype("<i4"),
                           np.array([90, 90, 180], "<i4"), np.array([180, 90, 90], "<i4")])
        size = rng.choice([0, 4, 11, 12, 13, 1000, FILE_SIZE - 12, FILE_SIZE - 12 - 8, FILE_SIZE - 4])
        if size >= FILE_SIZE - 20 and rng.random() < 0.5:
            body = rng.choice([rng.normal(0, 100, size // 8), np.full(size // 8, -1.0),
                               rng.choice([np.nan, np.inf, -np.inf, 1.0], size // 8)]).astype("<f8").tobytes()
        else:
            body = rng.bytes(int(size))
        raw = (np.asarray(head, "<i4").tobytes() + body)[: int(rng.choice([10 ** 9, rng.integers(0, 20)]))]
        p.write_bytes(raw)
        try:
            t = read_merl(p)
            assert np.isnan(t.stored).any() or (t.stored >= 0).all()
            kinds["ok"] += 1
        except MerlError as e:
            assert str(p) in str(e)
            kinds["error"] += 1
    assert kinds["ok"] >= 3 and kinds["error"] > 100       # both outcomes exercised
    assert time.time() - t0 < 60
