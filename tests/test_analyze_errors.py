"""brdfcl analyze with bad input and unwritable outputs: as fit-all, one line per problem, no traceback."""
import os
import subprocess
import sys

import pytest

from brdfcl.app.analyze import Analyses, analyze
from brdfcl.data.merl import FILE_SIZE, MerlError

CLI = [sys.executable, "-m", "brdfcl.app.cli"]
GOOD = "synth-fabric"
FAST = ["--quiet", "--no-figures", "--free-peak"]     # --free-peak: three fits per material, not five


def cli(*args):
    return subprocess.run(CLI + [str(a) for a in args], capture_output=True, text=True)


def one_error_line(r):
    """The run ended with exit status 2 and exactly one line, `brdfcl: error: ...`, and no traceback."""
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr
    errors = [ln for ln in r.stderr.splitlines() if ln.strip() and not ln.startswith("skipped:")]
    assert len(errors) == 1 and errors[0].startswith("brdfcl: error: "), r.stderr
    return errors[0]


def bad_files(d, good_bytes):
    (d / "truncated.binary").write_bytes(good_bytes[:FILE_SIZE // 3])
    (d / "text.binary").write_text("not a BRDF\n" * 50)
    return {"truncated.binary": "wrong size", "text.binary": "wrong header"}


@pytest.fixture()
def mixed(demo_db, tmp_path):
    d = tmp_path / "db"
    d.mkdir()
    (d / f"{GOOD}.binary").symlink_to(demo_db / f"{GOOD}.binary")
    problems = bad_files(d, (demo_db / f"{GOOD}.binary").read_bytes()[:FILE_SIZE // 3 + 1])
    return d, problems


@pytest.fixture()
def only_bad(demo_db, tmp_path):
    d = tmp_path / "bad"
    d.mkdir()
    return d, bad_files(d, (demo_db / f"{GOOD}.binary").read_bytes()[:FILE_SIZE // 3 + 1])


@pytest.mark.slow
def test_bad_files_beside_good_ones(mixed, tmp_path):
    db, problems = mixed
    out = tmp_path / "out"
    r = cli("analyze", db, "--out", out, *FAST)
    assert r.returncode == 1, r.stderr                      # as fit-all: something was skipped
    assert "Traceback" not in r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == len(problems) and all(ln.startswith("skipped: ") for ln in lines), lines
    for name, problem in problems.items():
        assert any(str(db / name) in ln and problem in ln for ln in lines), (name, lines)
    assert "analysed 1 material" in r.stdout and "2 skipped" in r.stdout
    rows = (out / "analysis.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[1].startswith(f"{GOOD},")
    assert (out / f"{GOOD}.exr").is_file()


def test_api_reports_skipped_files(mixed):
    db, problems = mixed
    heard = []
    res = analyze(db, ct_peak=False, figures=False, on_skip=lambda path, why: heard.append((path, why)))
    assert isinstance(res, Analyses) and isinstance(res, list) and not res.ok
    assert [a.name for a in res] == [GOOD]
    assert sorted(os.path.basename(p) for p in res.skipped) == sorted(problems)
    assert sorted(heard) == sorted(res.skipped.items())
    for path, why in res.skipped.items():
        assert problems[os.path.basename(path)] in why


def test_only_bad_files(only_bad, tmp_path):
    db, problems = only_bad
    r = cli("analyze", db, "--out", tmp_path / "o", "--quiet")
    line = one_error_line(r)
    assert "no readable material" in line and str(db) in line and "2 files skipped" in line
    assert "broadcast" not in r.stderr
    assert len([ln for ln in r.stderr.splitlines() if ln.startswith("skipped: ")]) == len(problems)
    heard = []
    with pytest.raises(MerlError, match="no readable material"):
        analyze(db, on_skip=lambda path, why: heard.append(path))
    assert len(heard) == len(problems)


def test_unwritable_out_is_one_line_before_any_work(demo_db, tmp_path, monkeypatch):
    (tmp_path / "afile").write_text("x")
    r = cli("analyze", demo_db, "--out", tmp_path / "afile" / "sub", "--quiet")
    line = one_error_line(r)
    assert "cannot be written" in line and str(tmp_path / "afile" / "sub") in line
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "figures").write_text("a file where the figures go")
    line = one_error_line(cli("analyze", demo_db, "--out", tmp_path / "o", "--quiet"))
    assert "cannot be written" in line and str(tmp_path / "o" / "figures") in line

    import brdfcl.app.analyze

    def no_fitting(*a, **kw):
        raise AssertionError("fitting started before the output folder was checked")
    monkeypatch.setattr(brdfcl.app.analyze, "Fitter", no_fitting)
    with pytest.raises(OSError, match="cannot be written"):
        analyze(demo_db, tmp_path / "afile" / "sub")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_out(demo_db, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        line = one_error_line(cli("analyze", demo_db, "--out", ro, "--quiet"))
        assert "cannot be written" in line and str(ro) in line
    finally:
        ro.chmod(0o755)


@pytest.mark.parametrize("blocked, named", [
    (f"{GOOD}.exr.tmp.exr", f"{GOOD}.exr"),                                # OpenEXR: a RuntimeError
    (f"figures/{GOOD}_gradient.png.tmp.png", f"figures/{GOOD}_gradient.png"),   # matplotlib: an OSError
])
@pytest.mark.slow
def test_write_failure_mid_run_is_one_line(mixed, tmp_path, blocked, named):
    """The temporary file an output is written to is taken by a folder: the write fails after the fits."""
    db, _ = mixed
    out = tmp_path / "out"
    (out / blocked).mkdir(parents=True)
    args = ["--quiet", "--free-peak"] + (["--no-figures"] if named.endswith(".exr") else [])
    line = one_error_line(cli("analyze", db, "--out", out, *args))
    assert f"{out / named}: cannot write" in line, line

